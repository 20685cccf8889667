//! footscand's start-up (issue 18 item 6): its default config name found through
//! $FOOTSCAN_CONFIG_DIR from any working directory, a missing one named with every place
//! looked at, plain log lines on a piped stderr, and heightmap.png titled with the side (the
//! shipped pipeline measures it before the map is drawn), the view and the scan's subject.

mod daemon_support;

use daemon_support::{short_scanner_config, Footscand};
use footscan::io::HeightMapLabel;
use std::path::Path;
use std::process::{Command, Stdio};
use std::time::Duration;

/// footscand in `cwd` with its config environment inside `home` (no user or checkout files
/// of this machine in the way of what the test sets).
fn footscand(cwd: &Path, home: &Path) -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_footscand"));
    c.current_dir(cwd)
        .env("HOME", home)
        .env("XDG_CONFIG_HOME", home.join("xdg"))
        .env_remove("FOOTSCAN_CONFIG_DIR")
        .env_remove("FOOTSCAND_TOKEN")
        .env_remove("NO_COLOR")
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped());
    c
}

/// Whether the first title line of `img` reads `expected`: its pixels against the same line
/// drawn by footscan's renderer (the font itself is read back in tests/cli_small.rs).
fn title_reads(img: &image::RgbImage, label: &HeightMapLabel, expected: &str) -> bool {
    assert_eq!(label.title(), expected);
    let reference = footscan::io::render_heightmap(&[], 1.0, label).image;
    let (x0, y0) = (12, 4);
    let w = 8 * expected.len() as u32 + 8;
    (0..8).all(|y| {
        (x0..x0 + w)
            .all(|x| img.get_pixel_checked(x, y0 + y) == reference.get_pixel_checked(x, y0 + y))
    })
}

#[test]
fn config_from_the_config_dir_plain_logs_and_a_titled_heightmap() {
    let t = tempfile::tempdir().unwrap();
    let (work, home, cfg) = (t.path().join("w"), t.path().join("h"), t.path().join("c"));
    for d in [&work, &home, &cfg] {
        std::fs::create_dir_all(d).unwrap();
    }
    std::fs::write(cfg.join("scanner.toml"), short_scanner_config("")).unwrap();
    let archive = t.path().join("archive");
    std::fs::write(
        cfg.join("footscand.toml"),
        format!(
            "[daemon]\narchive = {:?}\nscanner_config = \"scanner.toml\"\n",
            archive.to_str().unwrap()
        ),
    )
    .unwrap();
    let mut cmd = footscand(&work, &home);
    cmd.env("FOOTSCAN_CONFIG_DIR", &cfg)
        .env("RUST_LOG", "info")
        .args(["--bind", "127.0.0.1:0"]);
    let mut d = Footscand::spawn(cmd, archive.clone(), None);
    let id = d.start_scan("p-0099");
    let end = d.wait_scan_end(Duration::from_secs(120));
    assert_ne!(end["state"], "failed", "{end}");
    let png = d.download(&id, "heightmap.png");
    let img = image::load_from_memory(&png).unwrap().to_rgb8();
    let label = HeightMapLabel {
        chosen: Some(footscan::measure::Side::Right),
        measured: Some(footscan::measure::Side::Right),
        subject: Some("p-0099".into()),
    };
    assert!(title_reads(
        &img,
        &label,
        "RIGHT foot (measured), plantar view seen from below, subject p-0099"
    ));
    // The check can fail: another subject does not read the same.
    let other = HeightMapLabel {
        subject: Some("p-0098".into()),
        ..label.clone()
    };
    assert!(!title_reads(&img, &other, &other.title()));
    assert!(d.terminate(Duration::from_secs(30)).success());
    let err = d.stderr();
    let used = cfg.join("footscand.toml");
    assert!(
        err.contains(&format!("config {}", used.display())),
        "the config used is not logged:\n{err}"
    );
    assert!(
        !err.contains('\u{1b}'),
        "colour codes on a piped stderr:\n{err}"
    );
    assert!(err.contains("INFO"), "no log lines:\n{err}");
}

#[test]
fn a_missing_config_lists_every_place() {
    let t = tempfile::tempdir().unwrap();
    let (work, home, cfg) = (t.path().join("w"), t.path().join("h"), t.path().join("c"));
    for d in [&work, &home, &cfg] {
        std::fs::create_dir_all(d).unwrap();
    }
    let o = footscand(&work, &home)
        .env("FOOTSCAN_CONFIG_DIR", &cfg)
        .args(["--config", "clinic.toml", "--bind", "127.0.0.1:0"])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success(), "{err}");
    let exe = Path::new(env!("CARGO_BIN_EXE_footscand"));
    let mut places = vec![
        work.join("clinic.toml"),
        work.join("config/clinic.toml"),
        cfg.join("clinic.toml"),
        home.join("xdg/footscan/clinic.toml"),
        Path::new("/etc/footscan/clinic.toml").to_path_buf(),
        exe.parent().unwrap().join("../share/footscan/clinic.toml"),
    ];
    let checkout =
        std::fs::canonicalize(Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")).unwrap();
    if exe.starts_with(&checkout) {
        places.push(checkout.join("config/clinic.toml"));
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
}
