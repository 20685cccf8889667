//! The patch's seams against the fitted parts for each G1 continuity on both real pairs
//! (issue 36 item 2; `cargo run --release -p footscan-last --example join_g1 [-- --cache DIR]
//! [--out DIR]`): per pair and continuity the normal jump at 2000 samples along each seam (max
//! / mean), the gap, the patch's curvature variation on the 96 x 24 grid of `join_keep` and on
//! 384 x 192, how far the patch strays from the nearer last, and the section patch's figures
//! (no fit) to compare; with `--out DIR` each join's outputs (zebra.png among them) and
//! zebra_gap.png (the gap alone, finer) in DIR/PAIR-CONTINUITY. The fits come from the fit cache (default target/fit-cache-g1), so
//! only the first run fits. The lasts are read from FOOTSCAN_DATA (default: the shared data
//! directory beside the repository).

use footscan_geom::mesh::Bvh;
use footscan_last::blend::fair::surface_fairness;
use footscan_last::join::{self, keep::Continuity, output, seam, study, zebra, JoinParams};
use std::path::PathBuf;

fn main() {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let data = std::env::var_os("FOOTSCAN_DATA")
        .map(PathBuf::from)
        .unwrap_or_else(|| root.join("../../../shared/data"));
    let args: Vec<String> = std::env::args().collect();
    let arg = |name: &str| {
        args.iter()
            .position(|a| a == name)
            .and_then(|i| args.get(i + 1))
            .map(PathBuf::from)
    };
    let cache = arg("--cache").unwrap_or_else(|| root.join("../../target/fit-cache-g1"));
    let out = arg("--out");
    let pairs = study::real_pairs(&data).expect("real last pairs (set FOOTSCAN_DATA)");
    for pair in &pairs {
        let runs = [
            (None, "section patch"),
            (Some(Continuity::G1), "G1"),
            (Some(Continuity::G1Greville), "G1Greville"),
            (Some(Continuity::G1Tangent), "G1Tangent"),
        ];
        for (c, what) in runs {
            let p = JoinParams {
                fit_parts: c.is_some(),
                continuity: c.unwrap_or_default(),
                fit_cache: Some(cache.clone()),
                ..JoinParams::default()
            };
            let j = join::join(&pair.back, &pair.toe, &p).unwrap();
            let sb = seam::seam(&j.back, 1.0, &j.patch, 0.0, 2000);
            let st = seam::seam(&j.patch, 1.0, &j.toe, 0.0, 2000);
            let (var, _) = surface_fairness(&j.patch, 96, 24);
            let (fine, _) = surface_fairness(&j.patch, 384, 192);
            // The largest principal curvature of the patch (384 x 192 cell centres), and
            // where in v: a band that bends the patch sharply would show here.
            let (mut kmax, mut kv) = (0.0f64, 0.0);
            for i in 0..384 {
                for k in 0..192 {
                    let (u, v) = ((i as f64 + 0.5) / 384.0, (k as f64 + 0.5) / 192.0);
                    let c = j.patch.curvature(u, v);
                    let m = c.k1.abs().max(c.k2.abs());
                    if m > kmax {
                        (kmax, kv) = (m, v);
                    }
                }
            }
            let (bb, tb) = (Bvh::new(&j.back_mesh), Bvh::new(&j.toe_mesh));
            let mut worst: f64 = 0.0;
            for i in 0..200 {
                for k in 0..=20 {
                    let q = j.patch.point(i as f64 / 200.0, k as f64 / 20.0);
                    let d = bb.closest_point(&q).unwrap().distance;
                    worst = worst.max(d.min(tb.closest_point(&q).unwrap().distance));
                }
            }
            println!(
                "{} {what}: normal jump back {:.3} / {:.4} deg, toe {:.3} / {:.4} deg (max / \
                 mean), gap {:.1e} / {:.1e} mm, curvature variation {var:.3e} ({fine:.3e} on \
                 384 x 192), largest curvature {kmax:.2} 1/mm at v {kv:.3}, curvature jump \
                 {:.2} / {:.2} 1/mm, {worst:.2} mm from the nearer last, join {:.0} ms",
                pair.name,
                sb.normal_max_deg,
                sb.normal_mean_deg,
                st.normal_max_deg,
                st.normal_mean_deg,
                sb.gap_max_mm,
                st.gap_max_mm,
                sb.curvature_abs_max,
                st.curvature_abs_max,
                j.timings.join
            );
            if let Some(o) = &out {
                let name = pair.name.split_whitespace().next().unwrap_or("pair");
                let d = o.join(format!("{name}-{}", what.replace(' ', "-")));
                std::fs::create_dir_all(&d).unwrap();
                output::write(&j, &d, "joined").unwrap();
                // The gap alone, finer (960 around, 0.25 mm along): a strip a few mm wide
                // next to a seam is what the band may show.
                let t = output::tessellate(&j, 960, 0.25);
                let seams: Vec<Vec<_>> = [(&j.back, 1.0), (&j.toe, 0.0)]
                    .iter()
                    .map(|(s, v)| (0..=400).map(|i| s.point(i as f64 / 400.0, *v)).collect())
                    .collect();
                let clip = (j.back_plane.origin.x - 3.0, j.toe_plane.origin.x + 3.0);
                let caption = format!("{} {what}: the gap, 3 mm either side", pair.name);
                zebra::zebra_png(&d.join("zebra_gap.png"), &t, clip, &seams, &caption).unwrap();
            }
        }
    }
}
