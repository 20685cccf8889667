//! `footscan last join` on the RoundTip pair (unitless meshes scaled by --length): the files
//! it promises, seams.json's figures within the seam targets, and a bad plane refused with a
//! message naming it. The lasts are read at test time (FOOTSCAN_DATA, default: the shared data
//! directory beside the repository).

use std::path::PathBuf;
use std::process::Command;

fn footscan() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_footscan"));
    c.current_dir(env!("CARGO_MANIFEST_DIR"));
    c
}

fn lasts_dir() -> PathBuf {
    let base = std::env::var_os("FOOTSCAN_DATA")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../shared/data"));
    let dir = base.join("lasts");
    assert!(
        dir.is_dir(),
        "the real lasts are not at {} (set FOOTSCAN_DATA to the directory holding lasts/)",
        dir.display()
    );
    dir
}

#[test]
fn last_join_writes_the_joined_last_and_its_seam_figures() {
    let lasts = lasts_dir();
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("joined");
    let o = footscan()
        .args(["last", "join", "--back"])
        .arg(lasts.join("Last_Heeled_RoundTip.stl"))
        .arg("--toe")
        .arg(lasts.join("Last_Flat_RoundTip.stl"))
        .args([
            "--length", "260", "--angle", "10", "--points", "300", "--aux", "2,2",
        ])
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&o.stdout);
    println!("{stdout}{}", String::from_utf8_lossy(&o.stderr));
    assert!(o.status.success());
    for f in [
        "joined.igs",
        "joined.step",
        "joined.stl",
        "seams.json",
        "network.json",
        "zebra.png",
        "views.png",
    ] {
        let p = out.join(f);
        assert!(
            p.metadata().map(|m| m.len() > 0).unwrap_or(false),
            "{} missing or empty",
            p.display()
        );
        assert!(stdout.contains(f), "{f} not reported");
    }
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("seams.json")).unwrap()).unwrap();
    assert_eq!(json["points_per_section"], 300);
    assert!(
        json["stl"].as_str().unwrap().starts_with("closed"),
        "{json}"
    );
    for seam in ["back_seam", "toe_seam"] {
        let s = &json["quality"][seam];
        assert!(s["gap_max_mm"].as_f64().unwrap() <= 0.01, "{s}");
        assert!(s["normal_max_deg"].as_f64().unwrap() <= 0.1, "{s}");
        assert!(s["curvature_rel_max"].as_f64().unwrap() <= 0.05, "{s}");
    }
    // At 10 deg the bundle gives up to 36 guides, less those too near the sole guides.
    assert!(json["guides"].as_u64().unwrap() >= 24, "{json}");
}

#[test]
fn last_join_refuses_a_plane_that_misses_the_last() {
    let lasts = lasts_dir();
    let dir = tempfile::tempdir().unwrap();
    let o = footscan()
        .args(["last", "join", "--back"])
        .arg(lasts.join("Last_Heeled_RoundTip.stl"))
        .arg("--toe")
        .arg(lasts.join("Last_Flat_RoundTip.stl"))
        .args(["--length", "260", "--toe-plane", "400"])
        .arg("--out")
        .arg(dir.path().join("x"))
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success());
    assert!(err.contains("toe last") && err.contains("400.0"), "{err}");
    assert!(
        !dir.path().join("x").exists(),
        "wrote output for a failed join"
    );
    let o = footscan()
        .args([
            "last",
            "join",
            "--back",
            "a.stl",
            "--toe",
            "b.stl",
            "--back-plane",
            "x%",
        ])
        .arg("--out")
        .arg(dir.path().join("y"))
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success());
    assert!(err.contains("a.stl"), "{err}");
}
