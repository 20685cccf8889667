//! The smaller clinic items of issue 18 (item 6), on the built `footscan` binary: where a
//! relative `--config` is looked up, plain log lines when stderr is not a terminal, the
//! heightmap's title, a re-scan that never mixes two scans in its folder, and `measure --out`
//! leaving the scan folder alone.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::time::SystemTime;

const BIN: &str = env!("CARGO_BIN_EXE_footscan");

fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// The binary in `cwd` with a clean config environment (`HOME` and `XDG_CONFIG_HOME` inside
/// `home`, no `FOOTSCAN_CONFIG_DIR`, no `NO_COLOR`).
fn footscan(cwd: &Path, home: &Path) -> Command {
    let mut c = Command::new(BIN);
    c.current_dir(cwd)
        .env("HOME", home)
        .env("XDG_CONFIG_HOME", home.join("xdg"))
        .env_remove("FOOTSCAN_CONFIG_DIR")
        .env_remove("NO_COLOR")
        .env_remove("RUST_LOG");
    c
}

fn text(o: &Output) -> String {
    format!(
        "status {:?}\nstdout:\n{}\nstderr:\n{}",
        o.status,
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    )
}

/// The shipped simulator config with another focal length, so which file was used shows in
/// the calibration it writes.
fn sim_config_with_f(f_px: f64) -> String {
    let s = std::fs::read_to_string(repo().join("config/sim.toml")).unwrap();
    assert!(
        s.contains("f_px = 2000.0"),
        "config/sim.toml changed its f_px"
    );
    s.replace("f_px = 2000.0", &format!("f_px = {f_px:.1}"))
}

/// `footscan sim-calibration` with the default `--config`: the f_px of the file it found.
fn default_config_f(cmd: &mut Command, out: &Path) -> f64 {
    let o = cmd
        .args(["sim-calibration", "--out"])
        .arg(out)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", text(&o));
    let cal: toml::Table = std::fs::read_to_string(out).unwrap().parse().unwrap();
    cal["model"]["f_px"].as_float().unwrap()
}

#[test]
fn relative_config_is_looked_up_and_a_miss_lists_the_places() {
    let t = tempfile::tempdir().unwrap();
    let (work, home, dir) = (t.path().join("w"), t.path().join("h"), t.path().join("c"));
    for d in [&work, &home, &dir, &home.join("xdg/footscan")] {
        std::fs::create_dir_all(d).unwrap();
    }
    let cal = t.path().join("cal.toml");

    // Nothing in the working directory nor the user's places: the checkout this binary was
    // built in (target/debug/footscan under the repository) has config/sim.toml.
    if Path::new(BIN).starts_with(repo()) {
        let f = default_config_f(&mut footscan(&work, &home), &cal);
        assert_eq!(f, 2000.0);
    }
    // /etc/footscan would come before the checkout: only checked when this machine has none.
    let etc = !Path::new("/etc/footscan/sim.toml").exists();
    // The user's config directory.
    std::fs::write(
        home.join("xdg/footscan/sim.toml"),
        sim_config_with_f(2200.0),
    )
    .unwrap();
    if etc {
        assert_eq!(default_config_f(&mut footscan(&work, &home), &cal), 2200.0);
    }
    // $FOOTSCAN_CONFIG_DIR before it.
    std::fs::write(dir.join("sim.toml"), sim_config_with_f(2100.0)).unwrap();
    let mut cmd = footscan(&work, &home);
    cmd.env("FOOTSCAN_CONFIG_DIR", &dir);
    assert_eq!(default_config_f(&mut cmd, &cal), 2100.0);
    // The working directory's config/ before that, and the working directory first.
    std::fs::create_dir_all(work.join("config")).unwrap();
    std::fs::write(work.join("config/sim.toml"), sim_config_with_f(2300.0)).unwrap();
    let mut cmd = footscan(&work, &home);
    cmd.env("FOOTSCAN_CONFIG_DIR", &dir);
    assert_eq!(default_config_f(&mut cmd, &cal), 2300.0);
    std::fs::write(work.join("sim.toml"), sim_config_with_f(2400.0)).unwrap();
    let mut cmd = footscan(&work, &home);
    cmd.env("FOOTSCAN_CONFIG_DIR", &dir);
    assert_eq!(default_config_f(&mut cmd, &cal), 2400.0);

    // A name found nowhere: the error names every place, in order, and writes nothing.
    let mut cmd = footscan(&work, &home);
    cmd.env("FOOTSCAN_CONFIG_DIR", &dir);
    let o = cmd
        .args(["scan", "--config", "clinic.toml", "--out", "s"])
        .output()
        .unwrap();
    assert!(!o.status.success(), "{}", text(&o));
    let err = String::from_utf8_lossy(&o.stderr);
    let exe_dir = Path::new(BIN).parent().unwrap();
    let mut places = vec![
        work.join("clinic.toml"),
        work.join("config/clinic.toml"),
        dir.join("clinic.toml"),
        home.join("xdg/footscan/clinic.toml"),
        PathBuf::from("/etc/footscan/clinic.toml"),
        exe_dir.join("../share/footscan/clinic.toml"),
    ];
    if Path::new(BIN).starts_with(repo()) {
        places.push(repo().join("config/clinic.toml"));
    }
    let mut at = 0;
    for p in &places {
        let s = p.display().to_string();
        let i = err[at..]
            .find(&s)
            .unwrap_or_else(|| panic!("{s} not listed (in order) in\n{err}"));
        at += i + s.len();
    }
    assert!(err.contains("config file clinic.toml not found"), "{err}");
    assert!(!work.join("s").exists());
    // An unset $FOOTSCAN_CONFIG_DIR is said to be unset.
    let o = footscan(&work, &home)
        .args(["verify", "--config", "clinic.toml", "--yes"])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        !o.status.success() && err.contains("$FOOTSCAN_CONFIG_DIR, not set"),
        "{}",
        text(&o)
    );
}

/// Name -> (size, modification time) of every file in `dir`.
fn listing(dir: &Path) -> BTreeMap<String, (u64, SystemTime)> {
    std::fs::read_dir(dir)
        .unwrap()
        .map(|e| {
            let e = e.unwrap();
            let m = e.metadata().unwrap();
            (
                e.file_name().to_string_lossy().into_owned(),
                (m.len(), m.modified().unwrap()),
            )
        })
        .collect()
}

/// Text of one title line of a PNG drawn with the 8x8 font (font8x8, as footscan draws it) in
/// the foreground grey, from `x0`: each 8 px cell matched against the printable ASCII glyphs.
fn read_title(img: &image::RgbImage, x0: u32, y: u32) -> String {
    use font8x8::UnicodeFonts;
    let fg = image::Rgb([230u8, 230, 230]);
    let mut s = String::new();
    let mut x = x0;
    while x + 8 <= img.width() {
        let cell: [u8; 8] = std::array::from_fn(|row| {
            (0..8).fold(0u8, |b, col| {
                b | (u8::from(*img.get_pixel(x + col, y + row as u32) == fg) << col)
            })
        });
        s.push(
            (' '..='~')
                .find(|&c| font8x8::BASIC_FONTS.get(c) == Some(cell))
                .unwrap_or('#'),
        );
        x += 8;
    }
    s.trim_end().to_string()
}

#[test]
fn rescan_keeps_both_scans_measure_out_writes_only_out_and_logs_are_plain() {
    let t = tempfile::tempdir().unwrap();
    let home = t.path().join("h");
    std::fs::create_dir_all(&home).unwrap();
    let dest = t.path().join("scan");
    let config = repo().join("config/sim.toml");

    // A first scan, stderr piped (not a terminal) with info logging: plain lines.
    let o = footscan(t.path(), &home)
        .env("RUST_LOG", "info")
        .arg("scan")
        .arg("--config")
        .arg(&config)
        .args(["--quiet", "--side", "right", "--out"])
        .arg(&dest)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", text(&o));
    assert!(
        String::from_utf8_lossy(&o.stderr).contains("foot measured"),
        "no info line on stderr: {}",
        text(&o)
    );
    assert!(
        !o.stderr.contains(&0x1b),
        "colour codes on a piped stderr: {}",
        text(&o)
    );
    let first = listing(&dest);
    for f in [
        "scan.json",
        "points.ply",
        "heightmap.png",
        "measurements.json",
        "plantar.png",
    ] {
        assert!(first.contains_key(f), "no {f} in {first:?}");
    }
    // Nothing is left beside it but the scan.
    assert_eq!(std::fs::read_dir(t.path()).unwrap().count(), 2);

    // heightmap.png says which foot, the view and (no subject on the command line) no more.
    let hm = image::open(dest.join("heightmap.png")).unwrap().to_rgb8();
    assert_eq!(
        read_title(&hm, 12, 4),
        "RIGHT foot (measured), plantar view seen from below"
    );
    assert!(read_title(&hm, 12, 16).starts_with("sole height, x "));

    // measure --out: only OUT is written; the scan folder keeps its files and times.
    let out = t.path().join("m");
    let o = footscan(t.path(), &home)
        .args(["measure", "--scan"])
        .arg(&dest)
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", text(&o));
    assert_eq!(
        listing(&dest),
        first,
        "measure --out changed the scan folder"
    );
    let read = |p: &Path| -> serde_json::Value {
        serde_json::from_slice(&std::fs::read(p).unwrap()).unwrap()
    };
    let scanned = read(&dest.join("measurements.json"));
    let again = read(&out.join("measurements.json"));
    let len = |v: &serde_json::Value| v["foot_length_mm"].as_f64().unwrap();
    assert!((len(&again) - len(&scanned)).abs() < 1e-9);
    let truth = read(&dest.join("truth.json"));
    let true_len = truth["length_mm"].as_f64().unwrap();
    assert!(
        (len(&again) - true_len).abs() < 3.0,
        "foot length {} against {true_len}",
        len(&again)
    );
    let png = image::open(out.join("plantar.png")).unwrap();
    assert!(png.width() > 600 && png.height() > 300);
    // --out FILE.json: the drawing beside it as FILE.png.
    let o = footscan(t.path(), &home)
        .args(["measure", "--no-model", "--scan"])
        .arg(&dest)
        .arg("--out")
        .arg(t.path().join("j/left.json"))
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", text(&o));
    assert_eq!(
        listing(&dest),
        first,
        "measure --out changed the scan folder"
    );
    assert_eq!(
        listing(&t.path().join("j")).keys().collect::<Vec<_>>(),
        ["left.json", "left.png"]
    );

    // A second scan into the same folder that fails after it started (nothing on the glass,
    // a short pass: the foot cannot be measured and measure.foot is required).
    let failing = t.path().join("failing.toml");
    let cfg = std::fs::read_to_string(&config)
        .unwrap()
        .replace("scene = \"foot\"", "scene = \"empty\"")
        .replace("end_mm = 320.0", "end_mm = 60.0");
    std::fs::write(&failing, cfg).unwrap();
    let before_second = SystemTime::now();
    let o = footscan(t.path(), &home)
        .arg("scan")
        .arg("--config")
        .arg(&failing)
        .args(["--quiet", "--out"])
        .arg(&dest)
        .output()
        .unwrap();
    let said = text(&o);
    assert_eq!(o.status.code(), Some(1), "a failed scan exits 1\n{said}");
    let json = read(&dest.join("scan.json"));
    let status = json["status"].as_str().unwrap().to_string();
    assert!(
        status != "complete" && status != "complete with warnings",
        "the second scan was meant to fail: {status}\n{said}"
    );
    assert!(json["reason"].as_str().is_some_and(|r| !r.is_empty()));
    // The folder holds the second scan alone: every file written by it.
    let second = listing(&dest);
    for (name, (_, mtime)) in &second {
        assert!(
            *mtime >= before_second,
            "{name} in {} is from the first scan: a mix\n{said}",
            dest.display()
        );
    }
    assert!(
        !second.contains_key("measurements.json"),
        "{second:?}\n{said}"
    );
    // The first scan is kept whole beside it, as the command said.
    let kept: Vec<PathBuf> = std::fs::read_dir(t.path())
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| {
            p.file_name()
                .unwrap()
                .to_string_lossy()
                .starts_with("scan.previous-")
        })
        .collect();
    assert_eq!(kept.len(), 1, "{kept:?}\n{said}");
    assert_eq!(listing(&kept[0]), first);
    assert!(
        String::from_utf8_lossy(&o.stderr).contains(&kept[0].display().to_string()),
        "{said}"
    );
    // And no staging folder is left.
    let left: Vec<_> = std::fs::read_dir(t.path())
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.contains(".partial-"))
        .collect();
    assert!(left.is_empty(), "{left:?}");
}
