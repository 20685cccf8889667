//! footscand returns an adjusted last with a scan: a scanner config whose pipeline ends in
//! `last.adjust` (a real last, read at test time), a whole-foot scan over HTTP, and the last's
//! files listed with their content types and downloadable beside the scan's; the dashboard
//! shows deviation.png when the scan has one (tests/dashboard_chromium.rs covers the page).
//! The same scan then gets the clinic's customized last: the fitter's girths posted with a
//! stock last of the configured collection, a job that ends with every rule met and the
//! last's files downloadable; bad requests refused naming the input, a failed job kept with
//! its reason, a job cut off by a stop read as failed after the restart; in headless
//! Chromium the Result card shows the job's rules and files and makes another last from its
//! form (screenshot target/dashboard-last.png).

mod daemon_support;

use daemon_support::chromium::Browser;
use daemon_support::*;
use std::path::PathBuf;
use std::time::Duration;

fn lasts_dir() -> PathBuf {
    let base = std::env::var_os("FOOTSCAN_DATA")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data"));
    base.join("lasts")
}

#[test]
fn a_scan_with_last_adjust_offers_the_adjusted_last() {
    let dir = tempfile::tempdir().unwrap();
    let (cmd, archive) = command(dir.path(), &Opts::default());
    let stock = dir.path().join("stock");
    make_stock_collection(&stock);
    let daemon_cfg = dir.path().join("footscand.toml");
    let mut cfg = std::fs::read_to_string(&daemon_cfg).unwrap();
    cfg.push_str(&format!(
        "\n[lasts]\nstock_dir = {:?}\n",
        stock.display().to_string()
    ));
    std::fs::write(&daemon_cfg, cfg).unwrap();
    // The whole foot (0..320 mm at 1 mm a frame) so it is measured whole, then the last.
    let last = lasts_dir().join("Last_Flat_RoundTip.stl");
    assert!(
        last.is_file(),
        "{} missing (set FOOTSCAN_DATA)",
        last.display()
    );
    let cfg = short_scanner_config("")
        .replace("start_mm = 60.0", "start_mm = 0.0")
        .replace("end_mm = 200.0", "end_mm = 320.0")
        + &format!(
            "\n[[pipeline.stages]]\nstage = \"last.adjust\"\nlast = {:?}\nlength_mm = 262.0\n",
            last.display().to_string()
        );
    std::fs::write(dir.path().join("scanner.toml"), cfg).unwrap();
    let mut d = Footscand::spawn(cmd, archive.clone(), None);
    let id = d.start_scan("last-01");
    let end = d.wait_scan_end(Duration::from_secs(120));
    assert_eq!(end["state"], "complete", "{end}\n{}", d.stderr());
    let rec = d.record(&id);
    let arts = rec["artifacts"].as_array().unwrap();
    let kind = |n: &str| {
        arts.iter()
            .find(|a| a["name"] == n)
            .unwrap_or_else(|| panic!("{n} not listed: {arts:?}"))["content_type"]
            .as_str()
            .unwrap()
            .to_string()
    };
    assert_eq!(kind("deviation.png"), "image/png");
    assert_eq!(kind("bottom.igs"), "model/iges");
    assert_eq!(kind("bottom.step"), "model/step");
    assert_eq!(kind("last_adjusted.stl"), "model/stl");
    let r: Value = serde_json::from_slice(&d.download(&id, "adjust.json")).unwrap();
    let after = &r["after"];
    println!("adjust.json after: {after}");
    assert!(after["outline_rms_mm"].as_f64().unwrap() <= 0.3);
    assert!(after["height_rms_mm"].as_f64().unwrap() <= 0.3);
    let png = d.download(&id, "deviation.png");
    assert_eq!(&png[1..4], b"PNG");
    let igs = d.download(&id, "bottom.igs");
    assert!(
        String::from_utf8_lossy(&igs).contains("128"),
        "IGES with a B-spline surface"
    );
    customized_last(&d, &id);
    dashboard_makes_a_last(&d, &id, dir.path());
    viewer_draws_the_last(&d, &id, dir.path());
    dashboard_marks_a_last_that_could_not_be_made(&d, &id, dir.path());
    // A job cut off by a stop reads as failed once the daemon is back.
    assert!(d.terminate(Duration::from_secs(20)).success());
    let scan_dir = archive.join(&id);
    mark_job_running(&archive, &id, "last");
    let (cmd, archive) = command_keeping(dir.path());
    let d = Footscand::spawn(cmd, archive, None);
    let j = d.get_json(&format!("/api/scans/{id}/last"));
    assert_eq!(j["state"], "failed", "{j}");
    assert!(j["reason"].as_str().unwrap().contains("stopped"), "{j}");
    // The earlier last's files are still there.
    assert_eq!(
        d.get(&format!("/api/scans/{id}/last/last.stl")).status(),
        200
    );
    // A visit holding the scan is not deleted while a last is being made for it: the job
    // writes its files into the scan's directory when it ends, which brought the deleted
    // scan's directory back.
    let (s, visit) = d.post("/api/visits", r#"{"patient": "last-01"}"#);
    assert_eq!(s, 201, "{visit}");
    let vid = visit["id"].as_str().unwrap().to_string();
    let (s, v) = d.post(
        &format!("/api/visits/{vid}/scans"),
        &format!(r#"{{"scan": "{id}"}}"#),
    );
    assert_eq!(s, 200, "{v}");
    let (s, v) = d.post(
        &format!("/api/scans/{id}/last"),
        r#"{"girths": {"ball": 260.0, "instep": 248.0, "long_heel": 367.0, "ankle": 200.5}, "stock": "sim-245-right.stl"}"#,
    );
    assert_eq!(s, 202, "{v}");
    let (s, v) = d.delete(&format!("/api/visits/{vid}"));
    assert_eq!(s, 409, "{v}");
    assert!(v["error"].as_str().unwrap().contains(&id), "{v}");
    assert_eq!(wait_last(&d, &id)["state"], "done");
    let (s, v) = d.delete(&format!("/api/visits/{vid}"));
    assert_eq!(s, 200, "{v}");
    assert_eq!(v["scans_deleted"][0], id.as_str(), "{v}");
    assert!(!scan_dir.exists(), "{} is back", scan_dir.display());
}

/// The daemon's command on the configs already in `dir` (the test's own [lasts] kept).
fn command_keeping(dir: &std::path::Path) -> (std::process::Command, PathBuf) {
    let cfg = std::fs::read_to_string(dir.join("footscand.toml")).unwrap();
    let scanner = std::fs::read_to_string(dir.join("scanner.toml")).unwrap();
    let (cmd, archive) = command(dir, &Opts::default());
    std::fs::write(dir.join("footscand.toml"), cfg).unwrap();
    std::fs::write(dir.join("scanner.toml"), scanner).unwrap();
    (cmd, archive)
}

/// A stock collection: the whole-foot path's last for the simulator's 245 mm right foot (as
/// `footscan last customize --foot` makes it), and a file that is not a closed mesh.
fn make_stock_collection(dir: &std::path::Path) {
    use footscan_geom::mesh::Format;
    use footscan_last::customize::{customize, foot_in_frame, rules::RuleSet, Inputs};
    use footscan_sim::foot::{Foot, FootParams, MeshResolution};
    std::fs::create_dir_all(dir).unwrap();
    let f = Foot::new(FootParams {
        length_mm: 245.0,
        ..FootParams::default()
    })
    .unwrap();
    let m = f.mesh(MeshResolution::default());
    let (foot, frame) = foot_in_frame(m.tri_mesh(), "sim foot").unwrap();
    let inp = Inputs::default();
    let c = customize(foot, frame, &RuleSet::default_rules(), &inp).unwrap();
    c.last
        .write(dir.join("sim-245-right.stl"), Format::StlBinary)
        .unwrap();
    std::fs::write(dir.join("broken.stl"), b"solid broken\nendsolid broken\n").unwrap();
    std::fs::write(dir.join("notes.txt"), b"not a last").unwrap();
}

/// Wait for the scan's last job to end; its record.
fn wait_last(d: &Footscand, id: &str) -> Value {
    d.wait_job(id, "last", Duration::from_secs(120))
}

fn customized_last(d: &Footscand, id: &str) {
    let path = format!("/api/scans/{id}/last");
    // No job yet.
    let r = d.get(&path);
    assert_eq!(r.status(), 404);
    assert!(r.text().unwrap().contains("POST"));
    // The collection lists the meshes only.
    let lasts = d.get_json("/api/lasts");
    let names: Vec<&str> = lasts["lasts"]
        .as_array()
        .unwrap()
        .iter()
        .map(|l| l["name"].as_str().unwrap())
        .collect();
    assert_eq!(names, ["broken.stl", "sim-245-right.stl"], "{lasts}");
    // The collection ranked for this foot: the 245 mm foot's last first (a 250 mm scan: a
    // few millimetres of change), the file that is not a mesh last and not eligible, why said.
    let (s, v) = d.post(
        &format!("{path}/rank"),
        r#"{"girths": {"ball": 260.0, "instep": 248.0, "long_heel": 367.0, "ankle": 200.5}}"#,
    );
    assert_eq!(s, 200, "{v}");
    let ranked = v["lasts"].as_array().unwrap();
    assert_eq!(ranked.len(), 2, "{v}");
    assert_eq!(ranked[0]["name"], "sim-245-right.stl", "{v}");
    assert_eq!(ranked[0]["eligible"], true, "{v}");
    let change = ranked[0]["largest_change_mm"].as_f64().unwrap();
    assert!(change > 0.5 && change < 12.0, "{v}");
    assert_eq!(ranked[1]["name"], "broken.stl", "{v}");
    assert_eq!(ranked[1]["eligible"], false, "{v}");
    assert!(
        ranked[1]["cannot"][0]
            .as_str()
            .unwrap()
            .contains("not measured"),
        "{v}"
    );
    let (s, v) = d.post(
        &format!("{path}/rank"),
        r#"{"girths": {"ball": 26.0, "instep": 248.0, "long_heel": 367.0, "ankle": 200.5}}"#,
    );
    assert_eq!(s, 400, "{v}");
    assert!(v["error"].as_str().unwrap().contains("ball"), "{v}");
    // Bad requests: named, nothing started.
    let girths =
        r#""girths": {"ball": 260.0, "instep": 248.0, "long_heel": 367.0, "ankle": 200.5}"#;
    let (s, v) = d.post(&path, r#"{"girths": {"ball": 260.0, "instep": 248.0, "long_heel": 367.0}, "stock": "sim-245-right.stl"}"#);
    assert_eq!(s, 400, "{v}");
    assert!(v["error"].as_str().unwrap().contains("ankle"), "{v}");
    let (s, v) = d.post(&path, r#"{"girths": {"ball": 26.0, "instep": 248.0, "long_heel": 367.0, "ankle": 200.5}, "stock": "sim-245-right.stl"}"#);
    assert_eq!(s, 400, "{v}");
    assert!(v["error"].as_str().unwrap().contains("ball = 26 mm"), "{v}");
    let (s, v) = d.post(
        &path,
        &format!(r#"{{{girths}, "stock": "../../etc/passwd"}}"#),
    );
    assert_eq!(s, 400, "{v}");
    let (s, v) = d.post(&path, &format!(r#"{{{girths}, "stock": "nope.stl"}}"#));
    assert_eq!(s, 400, "{v}");
    assert!(
        v["error"].as_str().unwrap().contains("sim-245-right.stl"),
        "{v}"
    );
    let (s, v) = d.post(
        &path,
        &format!(r#"{{{girths}, "stock": "sim-245-right.stl", "heel_mm": 300}}"#),
    );
    assert_eq!(s, 400, "{v}");
    assert!(v["error"].as_str().unwrap().contains("heel_mm"), "{v}");
    assert_eq!(
        d.get(&path).status(),
        404,
        "a refused request starts nothing"
    );
    // A stock file that is not a closed mesh: the job fails, kept with its reason.
    let (s, v) = d.post(&path, &format!(r#"{{{girths}, "stock": "broken.stl"}}"#));
    assert_eq!(s, 202, "{v}");
    let j = wait_last(d, id);
    assert_eq!(j["state"], "failed", "{j}");
    assert!(j["reason"].as_str().unwrap().contains("broken.stl"), "{j}");
    // The last.
    let (s, v) = d.post(
        &path,
        &format!(r#"{{{girths}, "stock": "sim-245-right.stl", "shoe": "dress", "wearer": "man", "heel_mm": 25}}"#),
    );
    assert_eq!(s, 202, "{v}");
    assert_eq!(v["state"], "running", "{v}");
    let j = wait_last(d, id);
    println!("last job: {j:#}");
    assert_eq!(j["state"], "done", "{j}");
    let rules = j["rules"].as_array().unwrap();
    assert_eq!(rules.len(), 8, "{j}");
    assert!(rules.iter().all(|r| r["met"] == true), "{j}");
    let files = strings(&j["files"]);
    assert_eq!(
        files,
        [
            "last.stl",
            "last.igs",
            "last.step",
            "frame.igs",
            "report.json",
            "customize.png"
        ]
    );
    // The files as a CAD tool gets them.
    let get = |name: &str| d.job_file(id, "last", name);
    let (ty, stl) = get("last.stl");
    assert_eq!(ty, "model/stl");
    let rep: Value = serde_json::from_slice(&get("report.json").1).unwrap();
    let tris = stl_triangles(&stl);
    assert_eq!(rep["last_triangles"].as_u64().unwrap() as usize, tris);
    assert_eq!(rep["clearance"]["of"], "footprint");
    for (i, r) in rules.iter().enumerate() {
        assert_eq!(rep["rules"][i]["last_mm"], r["last_mm"]);
    }
    let (ty, step) = get("last.step");
    assert_eq!(ty, "model/step");
    assert!(step.starts_with(b"ISO-10303-21;"));
    let (ty, png) = get("customize.png");
    assert_eq!(ty, "image/png");
    assert_eq!(&png[1..4], b"PNG");
    let r = d.get(&format!("/api/scans/{id}/last/cloud.ply"));
    assert_eq!(r.status(), 400);
    assert!(r.text().unwrap().contains("last.stl"));
}

/// The Result card in Chromium: the job made over HTTP shown (8 rules met, 6 files), then a
/// last for a sport shoe made from the form.
fn dashboard_makes_a_last(d: &Footscand, id: &str, dir: &std::path::Path) {
    const WAIT: Duration = Duration::from_secs(60);
    let mut b = open_job_card(d, dir, id, "last", WAIT);
    let card = r#"(() => ({
        rules: [...document.querySelectorAll('#last-rules tbody tr')].map((r) => r.lastChild.textContent),
        files: [...document.querySelectorAll('#last-files a')].map((a) => a.textContent),
        stock: [...document.getElementById('last-stock').options].map((o) => o.value),
        state: document.getElementById('last-state').textContent,
      }))()"#;
    let c = b.eval(card);
    println!("dashboard last card: {c}");
    assert_eq!(c["rules"].as_array().unwrap().len(), 8, "{c}");
    // Every rule met; the ankle girth has no counterpart on a low-cut stock last ("n/a").
    let rules = c["rules"].as_array().unwrap();
    // (A measure the build-up for the footprint grew says so after the "yes".)
    assert!(
        rules[..7]
            .iter()
            .all(|r| r.as_str().unwrap().starts_with("yes")),
        "{c}"
    );
    assert_eq!(rules[7], "n/a", "{c}");
    assert_eq!(c["files"].as_array().unwrap().len(), 6, "{c}");
    assert_eq!(
        c["stock"],
        serde_json::json!(["broken.stl", "sim-245-right.stl"]),
        "{c}"
    );
    // Another last from the form: a sport shoe.
    b.eval(
        "(() => { const v = (id, x) => { document.getElementById(id).value = x; }; \
         v('last-ball', '260'); v('last-instep', '248'); v('last-long-heel', '367'); \
         v('last-ankle', '200.5'); v('last-stock', 'sim-245-right.stl'); v('last-shoe', 'sport'); \
         v('last-heel', '20'); })()",
    );
    // Ranked from the form: the table lists both files, the mesh last first and picked.
    b.click("last-rank");
    let ranked = "(() => { const t = document.getElementById('last-ranking-table'); \
                  return !!t && t.querySelectorAll('tbody tr').length === 2; })()";
    b.wait_for(ranked, WAIT);
    let r = b.eval(
        "(() => ({ rows: [...document.querySelectorAll('#last-ranking-table tbody tr')].map((r) => r.dataset.name), \
         picked: document.getElementById('last-stock').value }))()",
    );
    println!("dashboard ranking: {r}");
    assert_eq!(
        r["rows"],
        serde_json::json!(["sim-245-right.stl", "broken.stl"]),
        "{r}"
    );
    assert_eq!(r["picked"], "sim-245-right.stl", "{r}");
    b.click("last-make");
    b.wait_for(
        "(() => { const e = document.getElementById('last-state'); \
         return !!e && e.dataset.state === 'done' && e.textContent.includes('sport'); })()",
        WAIT,
    );
    let j = d.get_json(&format!("/api/scans/{id}/last"));
    assert_eq!(j["request"]["shoe"], "sport", "{j}");
    assert_eq!(j["request"]["heel_mm"], 20.0, "{j}");
    assert!(
        j["rules"]
            .as_array()
            .unwrap()
            .iter()
            .all(|r| r["met"] == true),
        "{j}"
    );
    b.wait_for(
        "(() => { const i = document.getElementById('last-picture'); return !!i && i.complete && i.naturalWidth > 0; })()",
        WAIT,
    );
    b.eval("document.getElementById('last').scrollIntoView()");
    b.screenshot(
        &daemon_support::chromium::target_png("dashboard-last.png"),
        Some("last"),
    );
}

/// The ranking is a forecast from the stock's stations: with a long-heel girth of 600 mm the
/// 245 mm last still ranks first (eligible: its size is right) but the solve cannot meet the
/// rule (it stops 150 mm short; at 420-500 mm the solve comes within 0.1-0.9 mm of every
/// rule, met or not by a hair from one simulated scan to the next, so no test of a failure). The card then marks that row as not made, with the job's reason,
/// takes it out of the choice, and says that no other last can be made (the other file is not
/// a last); ranked again for the same request, the row is marked again.
fn dashboard_marks_a_last_that_could_not_be_made(d: &Footscand, id: &str, dir: &std::path::Path) {
    const WAIT: Duration = Duration::from_secs(90);
    let mut b = Browser::launch(&dir.join("profile-failed"), 1280, 2400);
    b.open(
        &format!("{}/", d.base),
        "typeof renderLast === 'function'",
        WAIT,
    );
    b.eval(&format!("loadResult({id:?})"));
    b.wait_for(
        "(() => { const e = document.getElementById('last-state'); return !!e && e.dataset.state === 'done'; })()",
        WAIT,
    );
    b.eval(
        "(() => { const v = (id, x) => { document.getElementById(id).value = x; }; \
         v('last-ball', '260'); v('last-instep', '248'); v('last-long-heel', '600'); \
         v('last-ankle', '200.5'); v('last-shoe', 'dress'); v('last-heel', ''); })()",
    );
    let ranked = "(() => { const t = document.getElementById('last-ranking-table'); \
                  return !!t && t.querySelectorAll('tbody tr').length === 2; })()";
    b.click("last-rank");
    b.wait_for(ranked, WAIT);
    let first = b.eval(
        "(() => { const r = document.querySelector('#last-ranking-table tbody tr'); \
         return { name: r.dataset.name, usable: !r.querySelector('button').disabled, \
         picked: document.getElementById('last-stock').value }; })()",
    );
    assert_eq!(first["name"], "sim-245-right.stl", "{first}");
    assert_eq!(first["usable"], true, "ranked eligible: {first}");
    assert_eq!(first["picked"], "sim-245-right.stl", "{first}");
    b.click("last-make");
    b.wait_for(
        "(() => { const e = document.getElementById('last-state'); return !!e && e.dataset.state === 'failed'; })()",
        WAIT,
    );
    let marked = "(() => { const r = document.querySelector('#last-ranking-table tbody tr'); \
         const n = document.getElementById('last-ranking-next'); \
         return { failed: r.dataset.failed || null, usable: !r.querySelector('button').disabled, \
         notes: r.cells[5].textContent, why: r.cells[5].title, next: n ? n.textContent : null }; })()";
    let m = b.eval(marked);
    println!("dashboard ranking after a failed job: {m}");
    let j = d.get_json(&format!("/api/scans/{id}/last"));
    assert_eq!(j["state"], "failed", "{j}");
    let reason = j["reason"].as_str().unwrap();
    assert!(reason.contains("long-heel"), "the job names the rule: {j}");
    // Each cause once (the stock's name and the solve's message were printed twice).
    assert_eq!(
        reason.matches("the rules cannot all be met").count(),
        1,
        "{reason}"
    );
    assert_eq!(m["failed"], "true", "{m}");
    assert_eq!(m["usable"], false, "{m}");
    assert!(
        m["notes"]
            .as_str()
            .unwrap()
            .starts_with("could not be made for this foot: the reason is below the form"),
        "{m}"
    );
    assert_eq!(m["why"], reason, "the whole reason on hover: {m}");
    assert!(m["next"].as_str().unwrap().contains("no other last"), "{m}");
    b.eval("document.getElementById('last-ranking').scrollIntoView()");
    b.screenshot(
        &daemon_support::chromium::target_png("dashboard-last-failed.png"),
        Some("last"),
    );
    // Ranked again for the same request: marked again (the job's record is the memory).
    b.click("last-rank");
    b.wait_for(
        "(() => { const r = document.querySelector('#last-ranking-table tbody tr'); return !!r && r.dataset.failed === 'true'; })()",
        WAIT,
    );
    // Another request (the foot's own long heel): the row is the ranking's again.
    b.eval("document.getElementById('last-long-heel').value = '367'");
    b.click("last-rank");
    b.wait_for(ranked, WAIT);
    let again = b.eval(marked);
    assert_eq!(again["failed"], Value::Null, "{again}");
    assert_eq!(again["usable"], true, "{again}");
}

/// The extent (x, y, z in glTF metres) of node `name` of a .glb, from its POSITION
/// accessor's bounds (required there by glTF).
fn glb_extent(bytes: &[u8], name: &str) -> [f64; 3] {
    let (lo, hi) = glb_bounds(bytes, name);
    [0, 1, 2].map(|d| hi[d] - lo[d])
}

/// The bounds (min, max; glTF metres) of node `name` of a .glb.
fn glb_bounds(bytes: &[u8], name: &str) -> ([f64; 3], [f64; 3]) {
    let jl = u32::from_le_bytes(bytes[12..16].try_into().unwrap()) as usize;
    let doc: Value = serde_json::from_slice(&bytes[20..20 + jl]).unwrap();
    let node = doc["nodes"]
        .as_array()
        .unwrap()
        .iter()
        .find(|n| n["name"] == name)
        .unwrap_or_else(|| panic!("a node named {name}"));
    let mesh = &doc["meshes"][node["mesh"].as_u64().unwrap() as usize];
    let acc = &doc["accessors"][mesh["primitives"][0]["attributes"]["POSITION"]
        .as_u64()
        .unwrap() as usize];
    let f = |k: &str, d: usize| acc[k][d].as_f64().unwrap();
    (
        [0, 1, 2].map(|d| f("min", d)),
        [0, 1, 2].map(|d| f("max", d)),
    )
}

/// view.js BACKGROUND.
const BACKGROUND: [u8; 3] = [0xf7, 0xf7, 0xf5];

/// The bounding box (x0, y0, x1, y1) and count of the pixels `keep` picks, the figure's
/// 4 px frame left out.
fn mask_box(img: &image::RgbImage, keep: impl Fn(u32, u32) -> bool) -> ([u32; 4], usize) {
    mask_box_in(img.dimensions(), keep)
}

fn mask_box_in((w, h): (u32, u32), keep: impl Fn(u32, u32) -> bool) -> ([u32; 4], usize) {
    let (mut b, mut n) = ([u32::MAX, u32::MAX, 0, 0], 0);
    for y in 4..h - 4 {
        for x in 4..w - 4 {
            if keep(x, y) {
                n += 1;
                b = [b[0].min(x), b[1].min(y), b[2].max(x), b[3].max(y)];
            }
        }
    }
    (b, n)
}

fn off_background(p: &image::Rgb<u8>) -> bool {
    (0..3).any(|c| (p[c] as i32 - BACKGROUND[c] as i32).abs() > 16)
}

/// The 3D view of the scan with its last (issue 35): the job's record gives the placement
/// (fitted to the footprint within 0.05 mm) and fit.glb (the last laid flat around the foot,
/// the foot coloured by its clearance). In headless Chromium (WebGL on SwiftShader), from the
/// top and the side, the same camera with the last hidden and shown: the last's translucent
/// blue covers a region whose aspect is the last's own (from fit.glb's bounds) and which holds
/// the foot's image, reaching past the foot's toes (the toe allowance). Screenshots:
/// target/dashboard-fit-{top,side}.png.
fn viewer_draws_the_last(d: &Footscand, id: &str, dir: &std::path::Path) {
    use daemon_support::chromium::{target_png, WEBGL};
    let j = d.get_json(&format!("/api/scans/{id}/last"));
    let fit = &j["fit"];
    println!("last job fit: {fit}");
    assert!(fit.is_object(), "no fit in the job: {j}");
    assert!(fit["residual_mm"].as_f64().unwrap() < 0.05, "{fit}");
    let r = d.get(&format!("/api/scans/{id}/last/fit.glb"));
    assert_eq!(r.status(), 200);
    assert_eq!(r.headers()["content-type"], "model/gltf-binary");
    let glb = r.bytes().unwrap().to_vec();
    let (foot, last) = (glb_extent(&glb, "foot"), glb_extent(&glb, "last"));
    let mm = |e: [f64; 3]| e.map(|v| (v * 1e4).round() / 10.0);
    let (fl, fh) = glb_bounds(&glb, "foot");
    let (ll, lh) = glb_bounds(&glb, "last");
    println!(
        "fit.glb: {} bytes; foot {:?} mm, last {:?} mm; foot {:?}..{:?}, last {:?}..{:?} mm",
        glb.len(),
        mm(foot),
        mm(last),
        mm(fl),
        mm(fh),
        mm(ll),
        mm(lh)
    );
    let mut b = Browser::launch_with(&dir.join("profile-fit"), 1280, 1800, &WEBGL);
    b.open(
        &format!("{}/", d.base),
        "typeof loadResult === 'function' && window.footscanViewer",
        Duration::from_secs(60),
    );
    b.eval(&format!("loadResult({id:?})"));
    b.wait_for(
        &format!("footscanViewer.id === {id:?} && footscanViewer.ready && !!footscanViewer.last"),
        Duration::from_secs(60),
    );
    let legend = b.eval(
        "document.getElementById('viewer-legend').hidden ? null : \
         document.getElementById('viewer-legend').textContent",
    );
    println!("legend: {legend}");
    assert!(legend.as_str().unwrap_or("").contains("mm"), "{legend}");
    b.eval("footscanViewer.showMarks(false)");
    // glTF x is the foot's length; across it, z the width (seen from the top), y the height.
    for (view, across) in [("top", 2usize), ("side", 1)] {
        b.eval(&format!("footscanViewer.setView({view:?})"));
        b.eval("footscanViewer.showLast(false)");
        std::thread::sleep(Duration::from_millis(300));
        let bare = b.screenshot(
            &target_png(&format!("dashboard-fit-{view}-foot.png")),
            Some("viewer"),
        );
        b.eval("footscanViewer.showLast(true)");
        std::thread::sleep(Duration::from_millis(300));
        let img = b.screenshot(
            &target_png(&format!("dashboard-fit-{view}.png")),
            Some("viewer"),
        );
        // (The element's box may round to a pixel more or less between the two shots.)
        let both = (
            img.width().min(bare.width()),
            img.height().min(bare.height()),
        );
        let (fb, nf) = mask_box(&bare, |x, y| off_background(bare.get_pixel(x, y)));
        let (lb, nl) = mask_box(&img, |x, y| off_background(img.get_pixel(x, y)));
        // Where only the last is: off the background now, background without it; blue.
        let (_, ring) = mask_box_in(both, |x, y| {
            off_background(img.get_pixel(x, y)) && !off_background(bare.get_pixel(x, y))
        });
        let (_, blue) = mask_box_in(both, |x, y| {
            let p = img.get_pixel(x, y);
            !off_background(bare.get_pixel(x, y)) && p[2] as i32 > p[0] as i32 + 15
        });
        let (lw, lh) = ((lb[2] - lb[0] + 1) as f64, (lb[3] - lb[1] + 1) as f64);
        let want = last[0] / last[across];
        println!(
            "{view}: foot {nf} px in {fb:?}, with the last {nl} px in {lb:?} (aspect {:.2}, \
             the last's {want:.2}); {ring} px of the last alone, {blue} of them blue",
            lw / lh
        );
        assert!(
            nf > 1000 && nl > nf,
            "{view}: the last adds nothing to the view"
        );
        assert!(
            (lw / lh / want - 1.0).abs() < 0.25,
            "{view}: the view with the last spans {lw} x {lh} px, the last is {want:.2} long to {}",
            if across == 2 { "wide" } else { "high" }
        );
        assert!(
            blue as f64 > 0.9 * ring as f64 && ring > 2000,
            "{view}: {ring} px show the last alone, {blue} of them in its translucent blue"
        );
        // The last holds the foot's image (a few px of the heel, behind the last by the
        // heel allowance, may stand out) and reaches past its toes.
        let slack = 0.04 * lw;
        assert!(
            fb[0] as f64 >= lb[0] as f64 - slack
                && fb[1] as f64 >= lb[1] as f64 - slack
                && fb[2] as f64 <= lb[2] as f64 + slack
                && fb[3] as f64 <= lb[3] as f64 + slack,
            "{view}: the foot's image {fb:?} is not inside the last's {lb:?}"
        );
    }
}
