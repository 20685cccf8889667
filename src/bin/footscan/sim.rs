//! `footscan sim ...`: the simulator's objects as files, with their analytic truth, so the
//! mesh stages (e.g. `footscan last customize`) can be run and checked without a scanner.

use anyhow::{Context, Result};
use clap::{Parser, Subcommand};
use footscan_geom::mesh::Format;
use footscan_sim::foot::{Foot, FootParams, MeshResolution, Side};
use serde_json::json;
use std::path::PathBuf;

#[derive(Parser)]
pub struct Args {
    #[command(subcommand)]
    what: What,
}

#[derive(Subcommand)]
enum What {
    /// The parametric foot as a closed mesh (binary STL, mm, z up, sole on z = 0), with its
    /// analytic length, widths, landmarks and girths in a JSON file beside it (same name,
    /// .json): what a whole-foot 3D scanner would give, and the truth to check against.
    Foot(FootArgs),
}

#[derive(Parser)]
pub struct FootArgs {
    /// Foot length, heel point to toe tip along the axis (mm): 220-300.
    #[arg(long, default_value_t = 260.0)]
    length: f64,
    #[arg(long, value_enum, default_value = "right")]
    side: crate::SideArg,
    /// Ball width / length: 0.36-0.44.
    #[arg(long, default_value_t = 0.40)]
    ball_width_ratio: f64,
    /// Axis rotation on the glass, counterclockwise seen from above (degrees): -20 to 20.
    #[arg(long, default_value_t = 0.0)]
    yaw_deg: f64,
    /// Sections along the axis and points around each.
    #[arg(long, default_value_t = 320)]
    stations: usize,
    #[arg(long, default_value_t = 160)]
    around: usize,
    /// The mesh file to write (.stl); the truth goes to the same name with .json.
    #[arg(long)]
    out: PathBuf,
}

pub fn run(a: Args) -> Result<()> {
    match a.what {
        What::Foot(f) => foot(f),
    }
}

fn foot(a: FootArgs) -> Result<()> {
    // Before any work: a missing directory would otherwise surface as a bare OS error from
    // the temporary file.
    let dir = a
        .out
        .parent()
        .filter(|d| !d.as_os_str().is_empty())
        .unwrap_or(std::path::Path::new("."));
    if !dir.is_dir() {
        anyhow::bail!(
            "--out {}: the directory {} does not exist (create it first)",
            a.out.display(),
            dir.display()
        );
    }
    let side = Side::from(a.side);
    let f = Foot::new(FootParams {
        length_mm: a.length,
        side,
        ball_width_ratio: a.ball_width_ratio,
        yaw_deg: a.yaw_deg,
        ..FootParams::default()
    })
    .map_err(|e| anyhow::anyhow!("sim foot: {e}", e = footscan_util::Chain(&e)))?;
    let m = f.mesh(MeshResolution {
        stations: a.stations,
        around: a.around,
    });
    let mesh = m.tri_mesh();
    mesh.check()
        .map_err(|d| anyhow::anyhow!("sim foot: the mesh is not closed: {d}"))?;
    let t = &m.truth;
    let truth = json!({
        "units": "mm, world frame: z up, sole on z = 0",
        "side": t.plan.side,
        "length_mm": t.length_mm,
        "ball_width_mm": t.ball_width_mm,
        "heel_width_mm": t.heel_width_mm,
        "axis_dir": t.axis_dir,
        "landmarks": {
            "O_heel_point": t.heel_point,
            "A_toe_tip": t.toe_tip,
            "P_hallux": t.hallux_point,
            "B_mt1": t.mt1,
            "C_mt5": t.mt5,
            "D_waist_inner": t.waist_inner,
            "E_waist_outer": t.waist_outer,
        },
        "girths_perpendicular_to_axis": t.girths.iter()
            .map(|(x, g)| json!({"x_from_heel_mm": x, "girth_mm": g})).collect::<Vec<_>>(),
        "dorsum_height": t.dorsum.iter()
            .map(|(x, h)| json!({"x_from_heel_mm": x, "height_mm": h})).collect::<Vec<_>>(),
        "plan": t.plan,
        "vertices": mesh.vertices.len(),
        "triangles": mesh.triangles.len(),
    });
    let json_path = a.out.with_extension("json");
    // The truth first, then the mesh: a mesh on disk always has its truth beside it.
    let text = serde_json::to_string_pretty(&truth)?;
    let tmp = json_path.with_extension("json.tmp");
    std::fs::write(&tmp, text).with_context(|| tmp.display().to_string())?;
    std::fs::rename(&tmp, &json_path).with_context(|| json_path.display().to_string())?;
    mesh.write(&a.out, Format::StlBinary)
        .with_context(|| a.out.display().to_string())?;
    println!(
        "{:?} foot {:.1} mm, ball width {:.2} mm, heel width {:.2} mm; {} triangles",
        side,
        t.length_mm,
        t.ball_width_mm,
        t.heel_width_mm,
        mesh.triangles.len()
    );
    println!("wrote {}", a.out.display());
    println!("wrote {}", json_path.display());
    Ok(())
}
