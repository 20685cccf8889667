//! `footscan detect` on recorded frames: PNG Gray8 and Gray16 files and a directory of them,
//! any image size; the CSV read back and checked against the simulator's truth.

use footscan_bench::detect::{noise_config, sweep_frames};
use footscan_hal::{PixelFormat, Pixels};
use footscan_sim::render::{NoiseConfig, RowTruth};
use std::path::Path;
use std::process::Command;

fn save_png(path: &Path, w: u32, h: u32, px: &Pixels) {
    match px {
        Pixels::Gray8(v) => image::GrayImage::from_raw(w, h, v.clone())
            .unwrap()
            .save(path),
        Pixels::Gray16(v) => image::ImageBuffer::<image::Luma<u16>, _>::from_raw(w, h, v.clone())
            .unwrap()
            .save(path),
    }
    .unwrap();
}

struct Row {
    frame: usize,
    row: usize,
    col: Option<f64>,
    quality: f64,
}

fn read_csv(path: &Path) -> Vec<Row> {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text.lines();
    assert_eq!(lines.next(), Some("frame,row,col,intensity,width,quality"));
    lines
        .map(|l| {
            let f: Vec<&str> = l.split(',').collect();
            assert_eq!(f.len(), 6, "{l}");
            Row {
                frame: f[0].parse().unwrap(),
                row: f[1].parse().unwrap(),
                col: (!f[2].is_empty()).then(|| f[2].parse().unwrap()),
                quality: f[5].parse().unwrap(),
            }
        })
        .collect()
}

fn footscan(args: &[&str]) -> std::process::Output {
    let out = Command::new(env!("CARGO_BIN_EXE_footscan"))
        .args(args)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "footscan {args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    out
}

#[test]
fn detect_writes_one_csv_line_per_row_matching_truth() {
    let dir = tempfile::tempdir().unwrap();
    let frames_dir = dir.path().join("frames");
    std::fs::create_dir(&frames_dir).unwrap();
    // Two Gray8 frames and one Gray16 frame in a directory (name order = frame order).
    let g8 = sweep_frames(&noise_config("default", 1.6), &[4.0], &[180.0], 9);
    let g16 = sweep_frames(
        &NoiseConfig {
            format: PixelFormat::Gray16,
            ..noise_config("default", 1.6)
        },
        &[12.0],
        &[],
        9,
    );
    let all: Vec<_> = g8.iter().chain(&g16).collect();
    for (k, (f, _)) in all.iter().enumerate() {
        save_png(
            &frames_dir.join(format!("f{k:03}.png")),
            f.width,
            f.height,
            &f.pixels,
        );
    }
    let csv = dir.path().join("peaks.csv");
    for det in ["bezier-plus", "bezier", "cog", "steger"] {
        footscan(&[
            "detect",
            "--input",
            frames_dir.to_str().unwrap(),
            "--detector",
            det,
            "--out",
            csv.to_str().unwrap(),
        ]);
        let rows = read_csv(&csv);
        assert_eq!(rows.len(), 3 * 1024, "{det}");
        let (mut n, mut s2) = (0usize, 0.0);
        for r in &rows {
            assert_eq!(
                r.row,
                rows.iter().position(|x| std::ptr::eq(x, r)).unwrap() % 1024
            );
            let truth = &all[r.frame].1.rows[r.row];
            match (truth, r.col) {
                (RowTruth::Line { col, .. }, Some(c)) => {
                    n += 1;
                    s2 += (c - col).powi(2);
                    assert!((0.0..=1.0).contains(&r.quality));
                }
                (RowTruth::NoLine, Some(c)) => panic!("{det}: line at {c} in an empty row"),
                (_, None) => assert_eq!(r.quality, 0.0),
            }
        }
        let truth_rows: usize = all.iter().map(|(_, t)| t.line_count()).sum();
        assert!(
            n as f64 > 0.99 * truth_rows as f64,
            "{det}: {n} of {truth_rows}"
        );
        let rms = (s2 / n as f64).sqrt();
        assert!(rms < 0.2, "{det}: rms {rms}");
    }
}

#[test]
fn detect_takes_files_of_any_size_and_a_threshold() {
    let dir = tempfile::tempdir().unwrap();
    // A small odd-sized image: a vertical line at column 20.3 over 37 rows, 45 px wide.
    let (w, h) = (45u32, 37u32);
    let px: Vec<u8> = (0..h)
        .flat_map(|_| {
            (0..w).map(|c| {
                let d = c as f64 - 20.3;
                (8.0 + 150.0 * (-d * d / (2.0 * 1.6 * 1.6)).exp()).round() as u8
            })
        })
        .collect();
    let a = dir.path().join("a.png");
    let b = dir.path().join("b.png");
    save_png(&a, w, h, &Pixels::Gray8(px.clone()));
    save_png(&b, w, h, &Pixels::Gray8(vec![8; px.len()]));
    let csv = dir.path().join("p.csv");
    footscan(&[
        "detect",
        "--input",
        b.to_str().unwrap(),
        a.to_str().unwrap(),
        "--detector",
        "parabolic",
        "--threshold",
        "40",
        "--out",
        csv.to_str().unwrap(),
    ]);
    let rows = read_csv(&csv);
    assert_eq!(rows.len(), 2 * h as usize);
    assert!(rows[..h as usize]
        .iter()
        .all(|r| r.frame == 0 && r.col.is_none()));
    assert!(rows[h as usize..]
        .iter()
        .all(|r| r.frame == 1 && (r.col.unwrap() - 20.3).abs() < 0.1));
    // A threshold above the line leaves every column empty.
    footscan(&[
        "detect",
        "--input",
        a.to_str().unwrap(),
        "--detector",
        "cog",
        "--threshold",
        "200",
        "--out",
        csv.to_str().unwrap(),
    ]);
    assert!(read_csv(&csv).iter().all(|r| r.col.is_none()));
    // Errors are reported, not panicked.
    let out = Command::new(env!("CARGO_BIN_EXE_footscan"))
        .args([
            "detect",
            "--input",
            "/nonexistent.png",
            "--out",
            csv.to_str().unwrap(),
        ])
        .output()
        .unwrap();
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("nonexistent"));
}
