//! `footscan last ...`: shoe-last stages on meshes.

use anyhow::{Context, Result};
use clap::{Parser, Subcommand};
use footscan::lastfit::{adjust_scan, AdjustScanOptions};
use footscan_geom::mesh::Units;
use footscan_last::adjust::last::LastOptions;
use std::path::PathBuf;

#[derive(Parser)]
pub struct Args {
    #[command(subcommand)]
    what: What,
}

#[derive(Subcommand)]
enum What {
    /// Join the toe part of one last to the back part of another, by a Gordon surface
    /// (--method gordon) or a blend of morph and extension (--method blend): writes
    /// joined.igs, joined.step, joined.stl (closed), seams.json, zebra.png and views.png to
    /// --out, and network.json (gordon) or slices.png (blend).
    Join(crate::last_join::JoinArgs),
    /// Adjust a last's bottom to a scanned foot (docs/method.md section 9): writes bottom.igs
    /// and bottom.step (the adjusted bottom as a B-spline surface), last_adjusted.stl (the
    /// whole last deformed to it, closed), deviation.png (heat map before and after) and
    /// adjust.json to --out, all or nothing.
    Adjust(AdjustArgs),
    /// A last made for one foot by the comfort rules (docs/method.md section 10).
    Customize(crate::last_customize::CustomizeArgs),
    /// Measure a last as shoemakers do (docs/method.md 9.3): landmarks, stick and bottom
    /// length, heel height, toe spring, bottom widths and girths; --picture draws where each
    /// was taken.
    Measure(MeasureArgs),
    /// Grade a last into a size run (docs/method.md 9.4): each size's last as STL and STEP,
    /// its measures and the achieved steps against the rule (grade.csv, steps.csv,
    /// grade.json) to --out, all or nothing.
    Grade(crate::last_grade::GradeArgs),
    /// Rank the shop's lasts by how little each must change to fit a scanned foot
    /// (docs/method.md 9.5) and customize the best one that succeeds into --out.
    Choose(crate::last_choose::ChooseArgs),
}

#[derive(Parser)]
pub struct MeasureArgs {
    /// The last: a closed mesh (STL, OBJ or PLY) or a scanned point cloud (.asc, .xyz,
    /// .pts: x y z per line, made a closed mesh round its outside), z up, heel to toe along
    /// any horizontal direction.
    last: PathBuf,
    /// Units of the last file: mm, m, or auto (decided from the size).
    #[arg(long, default_value = "auto")]
    units: Units,
    /// Scale the last so its longest side is this many mm (for unitless meshes): 50-500.
    #[arg(long, value_parser = last_length)]
    length: Option<f64>,
    /// Print the measures as JSON instead of a table.
    #[arg(long)]
    json: bool,
    /// Draw the side and top views with the landmarks and girths into this PNG.
    #[arg(long)]
    picture: Option<PathBuf>,
}

#[derive(Parser)]
pub struct AdjustArgs {
    /// Scan directory holding grid.bin and measurements.json (a scan whose pipeline ran
    /// measure.foot, or one `footscan measure` has measured).
    #[arg(long)]
    scan: PathBuf,
    /// The last: a mesh file (STL, OBJ or PLY; a closed mesh, or an XYZ point cloud), or the
    /// directory of a scan of the last's bottom (`footscan scan` with a last on the glass;
    /// its grid.bin): then the bottom is adjusted and there is no whole last to deform.
    #[arg(long)]
    last: PathBuf,
    /// Units of the last file: mm, m, or auto (decided from the size).
    #[arg(long, default_value = "auto")]
    units: Units,
    /// Scale the last so its length is this many mm (for unitless meshes): 50-500.
    #[arg(long, value_parser = last_length)]
    length: Option<f64>,
    /// Height over which the deformation of the whole last fades out (mm).
    #[arg(long, default_value_t = 30.0)]
    fade_mm: f64,
    /// Output directory (replaced as a whole once everything is written).
    #[arg(long)]
    out: PathBuf,
}

pub fn run(args: Args) -> Result<()> {
    match args.what {
        What::Join(a) => crate::last_join::run(a),
        What::Adjust(a) => run_adjust(a),
        What::Customize(a) => crate::last_customize::run(a),
        What::Measure(a) => run_measure(a),
        What::Grade(a) => crate::last_grade::run(a),
        What::Choose(a) => crate::last_choose::run(a),
    }
}

/// The same range the pipeline stage checks: a last is 50-500 mm long.
fn last_length(s: &str) -> Result<f64, String> {
    let l: f64 = s.parse().map_err(|e| format!("{s:?}: {e}"))?;
    if l > 50.0 && l < 500.0 {
        Ok(l)
    } else {
        Err(format!("{l} mm: a last is 50-500 mm long"))
    }
}

fn run_adjust(a: AdjustArgs) -> Result<()> {
    let last_opts = LastOptions {
        units: a.units,
        length_mm: a.length,
        ..LastOptions::default()
    };
    let opts = AdjustScanOptions::with_fade_mm(a.fade_mm)
        .map_err(|e| anyhow::anyhow!("--fade-mm: {e}"))?;
    let (d, w) = adjust_scan(&a.scan, &a.last, &last_opts, &opts, &a.out)?;
    let adj = &d.adjustment;
    println!(
        "{} on the foot of {}{}",
        a.last.display(),
        a.scan.display(),
        if adj.mirrored {
            " (last of the other side: mirrored)"
        } else {
            ""
        }
    );
    println!(
        "rigid fit: rotation {:.2} deg, shift ({:.2}, {:.2}) mm; eps {:.4} (at {:.1}, {:.1}), zeta {:.4}",
        adj.rotation_deg, adj.shift[0], adj.shift[1], adj.eps, adj.eps_at[0], adj.eps_at[1], adj.zeta
    );
    println!("deviation, bottom minus foot    before (rigid fit)    after");
    let (b, f) = (adj.before, adj.after);
    let rows = [
        ("height RMS (mm)", b.height_rms_mm, f.height_rms_mm),
        ("height max (mm)", b.height_max_mm, f.height_max_mm),
        (
            "footprint beyond 0.5 mm (%)",
            100.0 * b.share_beyond_0_5,
            100.0 * f.share_beyond_0_5,
        ),
        (
            "footprint uncovered (%)",
            100.0 * b.uncovered_share,
            100.0 * f.uncovered_share,
        ),
        ("outline RMS (mm)", b.outline_rms_mm, f.outline_rms_mm),
        ("outline max (mm)", b.outline_max_mm, f.outline_max_mm),
        ("landmarks max (mm)", b.landmark_max_mm, f.landmark_max_mm),
    ];
    for (name, x, y) in rows {
        println!("  {name:29} {x:12.3} {y:12.3}");
    }
    println!(
        "bottom surface: {} x {} control points, fit RMS {:.3} mm, max {:.3} mm",
        d.surface.surface.nu, d.surface.surface.nv, d.surface.rms_mm, d.surface.max_mm
    );
    match &d.deformed {
        Some((_, r)) => println!(
            "last deformed: fade {:.0} mm, largest change {:.2} mm, {} flipped triangles ({} vertices moved by up to {:.2} mm and slid on the bottom by up to {:.2} mm to undo folds), bottom vertices vs adjusted bottom RMS {:.3} max {:.3} mm, volume {:.0} -> {:.0} mm^3",
            r.fade_mm,
            r.max_displacement_mm,
            r.flipped_triangles,
            r.relaxed_vertices,
            r.relaxed_max_mm,
            r.slid_max_mm,
            r.bottom_rms_mm,
            r.bottom_max_mm,
            r.volume_before_mm3,
            r.volume_after_mm3
        ),
        None => println!("a scanned last bottom: the bottom is adjusted, no whole last to deform"),
    }
    println!(
        "adjust {:.1} ms, surface {:.1} ms, deform {:.1} ms",
        d.adjust_ms, d.surface_ms, d.deform_ms
    );
    for n in &d.report.notes {
        println!("note: {n}");
    }
    for f in &w.files {
        println!("wrote {}", f.display());
    }
    Ok(())
}

fn run_measure(a: MeasureArgs) -> Result<()> {
    use footscan_last::measure_last::{draw_measures, measure_last_file};
    let m = measure_last_file(&a.last, a.units, a.length)?;
    if a.json {
        println!("{}", serde_json::to_string_pretty(&m)?);
    } else {
        let side = match m.side {
            Some(s) => format!("{s:?}").to_lowercase(),
            None => "unknown".into(),
        };
        println!(
            "{}: {side} last, stood on its tread (pitch {:+.2} deg from its bottom plane)",
            a.last.display(),
            m.pitch_deg
        );
        for (name, v) in m.rows() {
            println!("  {name:18} {v:8.2} mm");
        }
        println!(
            "  joints at {:.1} % (MT1) and {:.1} % (MT5) of the stick length, waist at {:.1} %",
            100.0 * m.mt1_at,
            100.0 * m.mt5_at,
            100.0 * m.waist_at
        );
        let l = &m.landmarks;
        for (name, p) in l.named() {
            println!("  {name:18} ({:7.2}, {:7.2}, {:7.2}) mm", p.x, p.y, p.z);
        }
    }
    if let Some(p) = &a.picture {
        draw_measures(&m, p).with_context(|| format!("writing {}", p.display()))?;
        if !a.json {
            println!("wrote {}", p.display());
        }
    }
    Ok(())
}
