//! `footscan last ...`: shoe-last stages on meshes.

use anyhow::{bail, Context, Result};
use clap::{Parser, Subcommand};
use footscan::lastfit::{adjust_scan, AdjustScanOptions};
use footscan_geom::mesh::{TriMesh, Units};
use footscan_geom::plane::Plane;
use footscan_geom::{P3, V3};
use footscan_last::adjust::last::LastOptions;
use footscan_last::join::{self, output, JoinParams};
use std::path::PathBuf;

#[derive(Parser)]
pub struct Args {
    #[command(subcommand)]
    what: What,
}

#[derive(Subcommand)]
enum What {
    /// Join the toe part of one last to the back part of another through a Gordon surface:
    /// writes joined.igs, joined.step, joined.stl (closed), seams.json, network.json,
    /// zebra.png and views.png to --out.
    Join(JoinArgs),
    /// Adjust a last's bottom to a scanned foot (docs/method.md section 9): writes bottom.igs
    /// and bottom.step (the adjusted bottom as a B-spline surface), last_adjusted.stl (the
    /// whole last deformed to it, closed), deviation.png (heat map before and after) and
    /// adjust.json to --out, all or nothing.
    Adjust(AdjustArgs),
}

#[derive(Parser)]
pub struct AdjustArgs {
    /// Scan directory holding grid.bin and measurements.json (a scan whose pipeline ran
    /// measure.foot, or one `footscan measure` has measured).
    #[arg(long)]
    scan: PathBuf,
    /// The last (STL, OBJ or PLY; a closed mesh).
    #[arg(long)]
    last: PathBuf,
    /// Units of the last file: mm, m, or auto (decided from the size).
    #[arg(long, default_value = "auto")]
    units: Units,
    /// Scale the last so its length is this many mm (for unitless meshes).
    #[arg(long)]
    length: Option<f64>,
    /// Height over which the deformation of the whole last fades out (mm).
    #[arg(long, default_value_t = 30.0)]
    fade_mm: f64,
    /// Output directory (replaced as a whole once everything is written).
    #[arg(long)]
    out: PathBuf,
}

#[derive(Parser)]
pub struct JoinArgs {
    /// Last whose back part (heel to the back plane) is kept (STL, OBJ or PLY).
    #[arg(long)]
    back: PathBuf,
    /// Last whose toe part (toe plane to the tip) is kept.
    #[arg(long)]
    toe: PathBuf,
    /// Back cutting plane: `X` (mm along the last in the common frame, heel at 0), `P%` (of
    /// the back last's length), or `ox,oy,oz,nx,ny,nz` (normal towards the toe). Default 62%.
    #[arg(long)]
    back_plane: Option<String>,
    /// Toe cutting plane, as --back-plane (of the toe last's length). Default 70%.
    #[arg(long)]
    toe_plane: Option<String>,
    /// Auxiliary sections on the back and toe sides, `B,T` (or one number for both).
    #[arg(long, default_value = "2,2")]
    aux: String,
    /// Points per section.
    #[arg(long, default_value_t = 500)]
    points: usize,
    /// Rotation angle of the plane bundle that places the guides, degrees.
    #[arg(long, default_value_t = 45.0)]
    angle: f64,
    /// Units of both meshes: mm, m, or auto (decided from the size).
    #[arg(long, default_value = "auto")]
    units: Units,
    /// Scale both lasts so their length is this many mm (for unitless meshes).
    #[arg(long)]
    length: Option<f64>,
    /// Take the meshes as already placed in a common frame (x heel to toe, z up) instead of
    /// superimposing them at the ball.
    #[arg(long)]
    as_is: bool,
    /// Output directory (created if missing).
    #[arg(long)]
    out: PathBuf,
}

pub fn run(args: Args) -> Result<()> {
    match args.what {
        What::Join(a) => run_join(a),
        What::Adjust(a) => run_adjust(a),
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
    println!(
        "last deformed: fade {:.0} mm, largest change {:.2} mm, {} flipped triangles, volume {:.0} -> {:.0} mm^3",
        d.deform.fade_mm,
        d.deform.max_displacement_mm,
        d.deform.flipped_triangles,
        d.deform.volume_before_mm3,
        d.deform.volume_after_mm3
    );
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

/// Parse a plane argument against the placed last it cuts.
fn parse_plane(s: &str, placed: &TriMesh, which: &str) -> Result<Plane> {
    let bad = || {
        format!(
            "--{which}-plane {s:?}: expected X (mm along the last), P% (of its length) or \
             ox,oy,oz,nx,ny,nz"
        )
    };
    let b = placed.bbox();
    let across = |x: f64| {
        Plane::with_axis(P3::new(x, 0.5 * (b.min.y + b.max.y), 0.0), V3::x(), V3::y())
            .with_context(bad)
    };
    if let Some(p) = s.strip_suffix('%') {
        let f: f64 = p.trim().parse().ok().with_context(bad)?;
        if !(0.0..=100.0).contains(&f) {
            bail!("{}: the percentage must be 0 to 100", bad());
        }
        return across(b.min.x + f / 100.0 * b.extent().x);
    }
    let v: Vec<f64> = s
        .split(',')
        .map(|x| x.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .ok()
        .with_context(bad)?;
    match v.as_slice() {
        [x] => across(*x),
        [ox, oy, oz, nx, ny, nz] => {
            Plane::new(P3::new(*ox, *oy, *oz), V3::new(*nx, *ny, *nz)).with_context(bad)
        }
        _ => bail!("{}", bad()),
    }
}

fn run_join(a: JoinArgs) -> Result<()> {
    let load = |p: &PathBuf| -> Result<TriMesh> {
        Ok(TriMesh::load_solid(p, a.units, a.length)
            .with_context(|| format!("reading last {}", p.display()))?
            .0)
    };
    let (back, toe) = (load(&a.back)?, load(&a.toe)?);
    let aux: Vec<usize> = a
        .aux
        .split(',')
        .map(|x| x.trim().parse::<usize>())
        .collect::<Result<_, _>>()
        .ok()
        .with_context(|| format!("--aux {:?}: expected B,T or N (whole numbers)", a.aux))?;
    let (aux_back, aux_toe) = match aux.as_slice() {
        [n] => (*n, *n),
        [b, t] => (*b, *t),
        _ => bail!("--aux {:?}: expected B,T or N", a.aux),
    };
    let placement = if a.as_is {
        join::Placement::AsIs
    } else {
        join::Placement::Ball
    };
    let mut p = JoinParams {
        aux_back,
        aux_toe,
        points: a.points,
        angle_deg: a.angle,
        placement_back: placement,
        placement_toe: placement,
        ..JoinParams::default()
    };
    if let Some(s) = &a.back_plane {
        p.back_plane = Some(parse_plane(s, &join::place(&back, &placement), "back")?);
    }
    if let Some(s) = &a.toe_plane {
        p.toe_plane = Some(parse_plane(s, &join::place(&toe, &placement), "toe")?);
    }
    let j = join::join(&back, &toe, &p)?;
    let name = format!(
        "{} back + {} toe",
        a.back.file_stem().unwrap_or_default().to_string_lossy(),
        a.toe.file_stem().unwrap_or_default().to_string_lossy()
    );
    let w = output::write(&j, &a.out, &name)
        .with_context(|| format!("writing into {}", a.out.display()))?;
    let q = &w.quality;
    let t = &j.timings;
    println!(
        "{name}: {} sections x {} guides, {} points per section, {} deg",
        j.network.sections.len(),
        j.network.guides.len(),
        a.points,
        a.angle
    );
    println!(
        "join {:.1} ms (place {:.1}, sections {:.1}, curves {:.1}, Gordon {:.1}, split {:.1})",
        t.total, t.place, t.sections, t.curves, t.gordon, t.split
    );
    for (s, m) in [("back", &q.back_seam), ("toe", &q.toe_seam)] {
        println!(
            "{s} seam: gap {:.1e} mm, normal jump {:.1e} deg, curvature jump {:.1e} (relative)",
            m.gap_max_mm, m.normal_max_deg, m.curvature_rel_max
        );
    }
    for (s, d) in [("back", &q.back_deviation), ("toe", &q.toe_deviation)] {
        println!(
            "{s} part from its mesh: rms {:.3} mm, max {:.3} mm",
            d.rms_mm, d.max_mm
        );
    }
    for f in &w.files {
        println!("wrote {}", f.display());
    }
    Ok(())
}
