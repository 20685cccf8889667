//! Writes a parametric last (last frame, millimetres) as binary STL.
//! usage: write_last TOE HEEL_MM LENGTH_MM OUT.stl   (TOE: round, pointed, square)

use footscan_geom::mesh::Format;
use footscan_sim::last::{Last, LastParams};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let a: Vec<String> = std::env::args().collect();
    if a.len() != 5 {
        return Err("usage: write_last TOE HEEL_MM LENGTH_MM OUT.stl".into());
    }
    let last = Last::new(LastParams {
        toe: a[1].parse()?,
        heel_mm: a[2].parse()?,
        length_mm: a[3].parse()?,
        ..LastParams::default()
    })?;
    last.local_mesh().write(&a[4], Format::StlBinary)?;
    let t = last.truth();
    println!(
        "{}: {} triangles, bottom length {:.1} mm, ball width {:.1} mm",
        a[4],
        last.local_mesh().triangles.len(),
        t.bottom_length_mm,
        t.ball_width_mm
    );
    Ok(())
}
