//! footscand makes orthotic insoles (daemon/insolejob.rs, docs/API.md "Insoles"): a whole-foot
//! simulated scan over HTTP, then an insole job from a preset with parameters changed, whose
//! files are downloaded and read back here (the STL's triangles, the heel's tilt cast on the
//! mesh, insole.json's parameters against those asked); bad parameters refused naming them
//! with nothing written, a foot-dependent one failing the job with its reason and nothing
//! written, a job cut off by a stop read as failed after the restart; a visit's left and right
//! feet made in one job with the preset's medial rearfoot post mirrored (medial on both: the
//! left insole is the right's mirror image); the dashboard's insole card in headless Chromium
//! (screenshot target/dashboard-insole.png).

mod daemon_support;

use daemon_support::*;
use footscan_geom::mesh::{Bvh, TriMesh};
use footscan_geom::{P3, V3};
use std::path::Path;
use std::time::Duration;

const JOB_LIMIT: Duration = Duration::from_secs(180);

/// The whole foot (0..320 mm at 1 mm a frame) so it is measured whole, of `side`.
fn whole_foot_config(side: &str) -> String {
    let c = short_scanner_config("")
        .replace("start_mm = 60.0", "start_mm = 0.0")
        .replace("end_mm = 200.0", "end_mm = 320.0");
    assert!(c.contains("side = \"right\""));
    c.replace("side = \"right\"", &format!("side = {side:?}"))
}

fn scan(d: &Footscand, subject: &str, side: &str) -> String {
    let (s, v) = d.post(
        "/api/scans",
        &format!(r#"{{"subject": "{subject}", "side": "{side}"}}"#),
    );
    assert_eq!(s, 202, "{v}");
    let id = v["id"].as_str().unwrap().to_string();
    let end = d.wait_scan_end(Duration::from_secs(300));
    assert_eq!(end["state"], "complete", "{end}\n{}", d.stderr());
    id
}

/// Wait for the scan's insole job to end; its record.
fn wait_insole(d: &Footscand, id: &str) -> Value {
    d.wait_job(id, "insole", JOB_LIMIT)
}

fn check<'a>(job: &'a Value, name: &str) -> &'a Value {
    job["figures"]["checks"]
        .as_array()
        .unwrap()
        .iter()
        .find(|c| c["name"] == name)
        .unwrap_or_else(|| panic!("no check {name}: {job}"))
}

/// File `name` of the scan's insole: its content type and bytes.
fn insole_file(d: &Footscand, id: &str, name: &str) -> (String, Vec<u8>) {
    d.job_file(id, "insole", name)
}

/// The downloaded insole.stl read back, with insole.json.
fn mesh_and_report(d: &Footscand, id: &str, dir: &Path) -> (TriMesh, Value) {
    let (ty, stl) = insole_file(d, id, "insole.stl");
    assert_eq!(ty, "model/stl");
    let tris = stl_triangles(&stl);
    let p = dir.join(format!("{id}.stl"));
    std::fs::write(&p, &stl).unwrap();
    let mesh = TriMesh::read(&p).unwrap();
    assert_eq!(mesh.triangles.len(), tris);
    let (ty, json) = insole_file(d, id, "insole.json");
    assert_eq!(ty, "application/json");
    (mesh, serde_json::from_slice(&json).unwrap())
}

/// The insole's top at (x, y) of its foot frame, cast down onto the mesh.
fn top(bvh: &Bvh, x: f64, y: f64) -> f64 {
    bvh.ray_cast(&P3::new(x, y, 500.0), &V3::new(0.0, 0.0, -1.0), 1000.0)
        .unwrap_or_else(|| panic!("no insole at ({x}, {y})"))
        .point
        .z
}

/// The top's rise toward +y across the heel (mm over 20 mm), 12 % of the length back.
fn heel_rise_plus_y(mesh: &TriMesh, report: &Value) -> f64 {
    let bvh = Bvh::new(mesh);
    let hc = &report["landmarks"]["heel_centre"];
    let (x, y) = (hc[0].as_f64().unwrap(), hc[1].as_f64().unwrap());
    top(&bvh, x, y + 10.0) - top(&bvh, x, y - 10.0)
}

#[test]
fn insole_jobs_for_a_scan_and_a_visit_with_mirrored_parameters() {
    let dir = tempfile::tempdir().unwrap();
    let (cmd, archive) = command(dir.path(), &Opts::default());
    std::fs::write(dir.path().join("scanner.toml"), whole_foot_config("right")).unwrap();
    let mut d = Footscand::spawn(cmd, archive.clone(), None);
    let right = scan(&d, "ins-01", "right");
    let path = format!("/api/scans/{right}/insole");
    let r = d.get(&path);
    assert_eq!(r.status(), 404);
    assert!(r.text().unwrap().contains("POST"));

    let p = d.get_json("/api/insole/presets");
    let names: Vec<&String> = p["presets"].as_object().unwrap().keys().collect();
    assert_eq!(names, ["correcting", "cushioning", "supportive"], "{p}");
    assert_eq!(p["presets"]["correcting"]["rearfoot_post_deg"], 4.0, "{p}");
    assert_eq!(p["presets"]["correcting"]["rearfoot_post_side"], "medial");

    // Bad requests: named with what is valid, nothing started, nothing written.
    for (body, words) in [
        (
            r#"{"preset": "correcting", "params": {"rearfoot_post_deg": 40}}"#,
            &["rearfoot_post_deg = 40", "10"][..],
        ),
        (
            r#"{"params": {"heel_cup": 6}}"#,
            &["heel_cup", "heel_cup_depth_mm"],
        ),
        (
            r#"{"params": {"top_cover_mm": 2.5, "base_thickness_mm": 3}}"#,
            &["top_cover_mm", "2"],
        ),
        (r#"{"preset": "firm"}"#, &["firm", "cushioning"]),
        (
            r#"{"shoe_bottom": true}"#,
            &["last_adjusted.stl", "last.adjust"],
        ),
        (r#"{"preset": "supportive", "colour": "red"}"#, &["colour"]),
    ] {
        let (s, v) = d.post(&path, body);
        assert!(s == 400 || s == 422, "{body}: {s} {v}");
        let e = v["error"].as_str().unwrap();
        for w in words {
            assert!(e.contains(w), "{body}: {w:?} not in {e:?}");
        }
    }
    assert_eq!(
        d.get(&path).status(),
        404,
        "a refused request starts nothing"
    );
    let insole_dir = archive.join(&right).join("insole");
    assert!(!insole_dir.exists());
    // A pad higher than this foot's arch: known once the foot is: the job fails, named.
    let (s, v) = d.post(
        &path,
        r#"{"params": {"arch_height_mm": 4, "met_pad_height_mm": 8}}"#,
    );
    assert_eq!(s, 202, "{v}");
    let j = wait_insole(&d, &right);
    assert_eq!(j["state"], "failed", "{j}");
    let why = j["reason"].as_str().unwrap();
    assert!(
        why.contains("met_pad_height_mm") && why.contains("nothing written"),
        "{j}"
    );
    assert!(!insole_dir.exists(), "a failed insole writes nothing");

    // The correcting preset without its rearfoot post, the pad changed.
    let (s, v) = d.post(
        &path,
        r#"{"preset": "correcting", "params": {"rearfoot_post_deg": 0, "met_pad_height_mm": 2.5}}"#,
    );
    assert_eq!(s, 202, "{v}");
    assert_eq!(v["state"], "running", "{v}");
    assert_eq!(v["params"]["met_pad_height_mm"], 2.5, "{v}");
    assert_eq!(v["params"]["heel_cup_depth_mm"], 15.0, "{v}");
    let j = wait_insole(&d, &right);
    println!("insole job: {j:#}");
    assert_eq!(j["state"], "done", "{j}");
    assert_eq!(j["figures"]["side"], "right", "{j}");
    assert_eq!(j["figures"]["ok"], true, "{j}");
    for (name, asked) in [
        ("met_pad_height", 2.5),
        ("heel_cup_depth", 15.0),
        ("rearfoot_post", 0.0),
        ("forefoot_post", 2.0),
    ] {
        let c = check(&j, name);
        assert_eq!(c["asked"].as_f64().unwrap(), asked, "{c}");
        let bound = if c["unit"] == "deg" { 0.3 } else { 0.2 };
        assert!(c["error"].as_f64().unwrap().abs() <= bound, "{c}");
    }
    let files = strings(&j["files"]);
    assert_eq!(
        files,
        [
            "insole.stl",
            "insole.3mf",
            "insole.step",
            "insole.json",
            "thickness.png",
            "top.png",
            "side.png"
        ]
    );
    // The files as a printer, a mill and a reader get them.
    let (base_mesh, rep) = mesh_and_report(&d, &right, dir.path());
    assert_eq!(rep["params"]["met_pad_height_mm"], 2.5, "{rep}");
    assert_eq!(rep["params"]["rearfoot_post_deg"], 0.0);
    assert_eq!(
        rep["mesh"]["triangles"].as_u64().unwrap() as usize,
        base_mesh.triangles.len()
    );
    base_mesh.check_closed().unwrap();
    let thinnest = j["figures"]["min_thickness_mm"].as_f64().unwrap();
    assert!(thinnest >= 4.0 - 1.0 - 1e-6, "{thinnest}");
    let (ty, mf) = insole_file(&d, &right, "insole.3mf");
    assert_eq!((ty.as_str(), &mf[..2]), ("model/3mf", &b"PK"[..]));
    let (ty, step) = insole_file(&d, &right, "insole.step");
    assert_eq!(ty, "model/step");
    assert!(step.starts_with(b"ISO-10303-21;"));
    for n in ["top.png", "side.png", "thickness.png"] {
        let (ty, png) = insole_file(&d, &right, n);
        assert_eq!((ty.as_str(), &png[1..4]), ("image/png", &b"PNG"[..]));
    }
    let r = d.get(&format!("/api/scans/{right}/insole/../scan.json"));
    assert_ne!(r.status(), 200);
    let r = d.get(&format!("/api/scans/{right}/insole/grid.bin"));
    assert_eq!(r.status(), 400);
    assert!(r.text().unwrap().contains("insole.stl"));
    let base_rise = heel_rise_plus_y(&base_mesh, &rep);

    dashboard_insole_card(&d, &right, dir.path());

    // A job cut off by a stop reads as failed once the daemon is back; its files stay.
    assert!(d.terminate(Duration::from_secs(20)).success());
    mark_job_running(&archive, &right, "insole");
    // Back with the left foot on the glass.
    let cfg = std::fs::read_to_string(dir.path().join("footscand.toml")).unwrap();
    let (cmd, archive) = command(dir.path(), &Opts::default());
    std::fs::write(dir.path().join("footscand.toml"), cfg).unwrap();
    std::fs::write(dir.path().join("scanner.toml"), whole_foot_config("left")).unwrap();
    let d = Footscand::spawn(cmd, archive, None);
    let j = d.get_json(&path);
    assert_eq!(j["state"], "failed", "{j}");
    assert!(j["reason"].as_str().unwrap().contains("stopped"), "{j}");
    assert_eq!(d.get(&format!("{path}/insole.stl")).status(), 200);

    // A visit's two feet: the correcting preset (4 deg medial rearfoot post) for both.
    let (s, visit) = d.post("/api/visits", r#"{"patient": "ins-01"}"#);
    assert_eq!(s, 201, "{visit}");
    let vid = visit["id"].as_str().unwrap().to_string();
    let add = |scan: &str| {
        let (s, v) = d.post(
            &format!("/api/visits/{vid}/scans"),
            &format!(r#"{{"scan": "{scan}"}}"#),
        );
        assert_eq!(s, 200, "{v}");
    };
    add(&right);
    let vpath = format!("/api/visits/{vid}/insole");
    let (s, v) = d.post(&vpath, r#"{"preset": "correcting"}"#);
    assert_eq!(s, 409, "{v}");
    assert!(
        v["error"].as_str().unwrap().contains("right foot only"),
        "{v}"
    );
    let left = scan(&d, "ins-01", "left");
    add(&left);
    let (s, v) = d.post(
        &vpath,
        r#"{"preset": "correcting", "left": {"rearfoot_post_deg": 40}}"#,
    );
    assert_eq!(s, 400, "{v}");
    assert!(
        v["error"]
            .as_str()
            .unwrap()
            .contains("left foot: rearfoot_post_deg = 40"),
        "{v}"
    );
    let (s, v) = d.post(&vpath, r#"{"preset": "correcting"}"#);
    assert_eq!(s, 202, "{v}");
    let jobs = v["jobs"].as_array().unwrap();
    assert_eq!(jobs.len(), 2, "{v}");
    assert_eq!(
        (jobs[0]["scan"].as_str(), jobs[1]["scan"].as_str()),
        (Some(left.as_str()), Some(right.as_str())),
        "{v}"
    );
    // One job at a time.
    let (s, v) = d.post(&path, r#"{"preset": "supportive"}"#);
    assert_eq!(s, 409, "{v}");
    assert!(
        v["error"].as_str().unwrap().contains("one at a time"),
        "{v}"
    );
    let (jl, jr) = (wait_insole(&d, &left), wait_insole(&d, &right));
    let mut rises = Vec::new();
    for (id, j, side) in [(&left, &jl, "left"), (&right, &jr, "right")] {
        println!("{side} insole job: {j:#}");
        assert_eq!(j["state"], "done", "{j}");
        assert_eq!(j["visit"], vid.as_str(), "{j}");
        assert_eq!(j["figures"]["side"], side, "{j}");
        assert_eq!(j["params"]["rearfoot_post_side"], "medial", "{j}");
        let c = check(j, "rearfoot_post");
        assert_eq!(c["asked"].as_f64().unwrap(), 4.0, "{c}");
        assert!(c["error"].as_f64().unwrap().abs() <= 0.3, "{c}");
        let (mesh, rep) = mesh_and_report(&d, id, dir.path());
        assert_eq!(rep["side"], side, "{rep}");
        rises.push(heel_rise_plus_y(&mesh, &rep));
    }
    // Medial is +y for a right foot and -y for a left one (the foot frame's y is to the left
    // seen from above). Against the right foot's insole without a post, the 4 deg post raises
    // the right insole's +y side and the left insole's -y side by 20 tan 4 deg = 1.40 mm over
    // the 20 mm across the heel; the heel cup and the foot's own shape are the same on both
    // feet (the simulated left foot is the right one's mirror image).
    let want = 20.0 * 4f64.to_radians().tan();
    let (left_rise, right_rise) = (rises[0], rises[1]);
    println!(
        "heel rise toward +y over 20 mm: right without post {base_rise:.3}, right with \
         {right_rise:.3}, left with {left_rise:.3} (the post: {want:.3})"
    );
    assert!(
        (right_rise - base_rise - want).abs() < 0.2,
        "right: {right_rise} - {base_rise} vs {want}"
    );
    assert!(
        (-left_rise - base_rise - want).abs() < 0.3,
        "left (mirrored): {} - {base_rise} vs {want}",
        -left_rise
    );
}

/// The insole card in Chromium: the job made over HTTP shown (its checks, files and
/// pictures), the presets filling the form, then an insole made from the form with the
/// cushioning preset and one parameter changed.
fn dashboard_insole_card(d: &Footscand, id: &str, dir: &Path) {
    const WAIT: Duration = Duration::from_secs(120);
    let mut b = open_job_card(d, dir, id, "insole", WAIT);
    let card = r#"(() => ({
        checks: [...document.querySelectorAll('#insole-checks tbody tr')].map((r) => r.lastChild.textContent),
        files: [...document.querySelectorAll('#insole-files a')].map((a) => a.textContent),
        cup: document.getElementById('insole-heel-cup-depth-mm').value,
        state: document.getElementById('insole-state').textContent,
      }))()"#;
    let c = b.eval(card);
    println!("dashboard insole card: {c}");
    let checks = c["checks"].as_array().unwrap();
    assert!(checks.len() >= 6, "{c}");
    assert!(
        checks
            .iter()
            .all(|x| x.as_str().unwrap().starts_with("yes")),
        "{c}"
    );
    assert_eq!(c["files"].as_array().unwrap().len(), 7, "{c}");
    assert_eq!(c["cup"], "12", "the supportive preset fills the form: {c}");
    assert!(
        c["state"]
            .as_str()
            .unwrap()
            .contains("met_pad_height_mm 2.5"),
        "{c}"
    );
    // From the form: the cushioning preset, its heel cup changed to 9 mm.
    b.eval(
        "(() => { const p = document.getElementById('insole-preset'); p.value = 'cushioning'; \
         p.dispatchEvent(new Event('change')); \
         document.getElementById('insole-heel-cup-depth-mm').value = '9'; })()",
    );
    let base = b.eval("document.getElementById('insole-base-thickness-mm').value");
    assert_eq!(base, "6", "the cushioning preset fills the form");
    b.click("insole-make");
    b.wait_for(
        "(() => { const e = document.getElementById('insole-state'); \
         return !!e && e.dataset.state === 'done' && e.textContent.includes('cushioning'); })()",
        WAIT,
    );
    let j = d.get_json(&format!("/api/scans/{id}/insole"));
    assert_eq!(j["request"]["preset"], "cushioning", "{j}");
    let posted = j["request"]["params"].as_object().unwrap();
    assert_eq!(posted.len(), 1, "only the change is posted: {j}");
    assert_eq!(posted["heel_cup_depth_mm"].as_f64(), Some(9.0), "{j}");
    assert_eq!(j["params"]["base_thickness_mm"], 6.0, "{j}");
    let c = check(&j, "heel_cup_depth");
    assert_eq!(c["asked"].as_f64().unwrap(), 9.0, "{c}");
    b.wait_for(
        "(() => { const i = [...document.querySelectorAll('#insole-pictures img')]; \
         return i.length === 3 && i.every((x) => x.complete && x.naturalWidth > 0); })()",
        WAIT,
    );
    b.eval("document.getElementById('insole').scrollIntoView()");
    b.screenshot(
        &daemon_support::chromium::target_png("dashboard-insole.png"),
        Some("insole"),
    );
}
