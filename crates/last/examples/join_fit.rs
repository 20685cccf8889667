//! The fits of the kept parts on both real pairs, timed (`cargo run --release -p footscan-last
//! --example join_fit [-- --dense] [--cache DIR]`): per part the fit's time and where it goes,
//! its distance from the mesh on the fit's check grid, on the quality's grid (240 x 120;
//! with `--dense` also 1200 x 600) and on 2000 x 31 points over the 3 v spans at the cut, the join's own time, the seams between the pieces and
//! against the original lasts; with `--cache DIR` each pair is joined twice with the fit cache
//! in DIR and both runs' fit times are printed. The lasts are read from FOOTSCAN_DATA (default:
//! the shared data directory beside the repository).

use footscan_last::join::{self, output, seam, study, JoinParams};
use std::path::PathBuf;

fn main() {
    let data = std::env::var_os("FOOTSCAN_DATA")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data"));
    let args: Vec<String> = std::env::args().collect();
    let dense = args.iter().any(|a| a == "--dense");
    let cache = args
        .iter()
        .position(|a| a == "--cache")
        .and_then(|i| args.get(i + 1))
        .map(PathBuf::from);
    let pairs = study::real_pairs(&data).expect("real last pairs (set FOOTSCAN_DATA)");
    for pair in &pairs {
        let p = JoinParams {
            fit_parts: true,
            fit_cache: cache.clone(),
            ..JoinParams::default()
        };
        let j = join::join(&pair.back, &pair.toe, &p).unwrap();
        if cache.is_some() {
            let again = join::join(&pair.back, &pair.toe, &p).unwrap();
            let (f0, f1) = (j.fits.unwrap(), again.fits.unwrap());
            println!(
                "{}: fit cache: first join {} / {}, fits {:.0} / {:.0} ms; second join {} / {}, \
                 {:.1} / {:.1} ms",
                pair.name,
                if f0[0].cached { "hit" } else { "miss" },
                if f0[1].cached { "hit" } else { "miss" },
                j.timings.fit_back,
                j.timings.fit_toe,
                if f1[0].cached { "hit" } else { "miss" },
                if f1[1].cached { "hit" } else { "miss" },
                again.timings.fit_back,
                again.timings.fit_toe
            );
        }
        let f = j.fits.unwrap();
        println!(
            "{}: join {:.1} ms without the fits",
            pair.name, j.timings.join
        );
        for (part, f, s, m) in [
            ("back", &f[0], &j.back, &j.back_mesh),
            ("toe", &f[1], &j.toe, &j.toe_mesh),
        ] {
            let q = seam::deviation(s, m, 240, 120);
            print!(
                "  {part}: fit {:.0} ms (setup {:.0}, solves {:.0}, checks {:.0}), {} rounds, \
                 {} x {} spans, check grid max {:.3} mm rms {:.4}, 240 x 120 max {:.3}",
                f.ms,
                f.setup_ms,
                f.solve_ms,
                f.check_ms,
                f.rounds,
                f.spans_u,
                f.spans_v,
                f.max_mm,
                f.rms_mm,
                q.max_mm
            );
            // Next to the cut (the fairing of the part's tangent field there moves the
            // surface): 2000 x 31 points over the 3 v spans at the cut.
            let kv: Vec<f64> = {
                let mut k = s.knots_v.clone();
                k.dedup();
                k
            };
            let n = kv.len();
            let (a, b) = if part == "back" {
                (kv[n - 4], kv[n - 1])
            } else {
                (kv[0], kv[3])
            };
            let bvh = footscan_geom::mesh::Bvh::new(m);
            let mut near: f64 = 0.0;
            for i in 0..2000 {
                for k in 0..=30 {
                    let p = s.point(i as f64 / 2000.0, a + (b - a) * k as f64 / 30.0);
                    near = near.max(bvh.closest_point(&p).unwrap().distance);
                }
            }
            print!(", next to the cut {near:.3}");
            if dense {
                let d = seam::deviation(s, m, 1200, 600);
                print!(
                    ", 1200 x 600 max {:.3} at ({:.1}, {:.1}, {:.1})",
                    d.max_mm, d.max_at[0], d.max_at[1], d.max_at[2]
                );
            }
            println!();
        }
        let q = output::quality(&j, 400).unwrap();
        for (n, s) in [("back", &q.back_seam), ("toe", &q.toe_seam)] {
            println!(
                "  {n} seam: gap {:.1e} mm, normal {:.3} / {:.4} deg max / mean",
                s.gap_max_mm, s.normal_max_deg, s.normal_mean_deg
            );
        }
        let q2 = output::quality(&j, 200).unwrap();
        for (n, o) in [
            ("back", &q.back_original),
            ("toe", &q.toe_original),
            ("back (200 samples)", &q2.back_original),
            ("toe (200 samples)", &q2.toe_original),
        ] {
            println!(
                "  {n} seam against the original: gap {:.3} mm, normal {:.2} / {:.2} deg max / mean",
                o.gap_max_mm, o.normal_max_deg, o.normal_mean_deg
            );
        }
        let (var, _) = footscan_last::blend::fair::surface_fairness(&j.patch, 96, 24);
        println!("  patch curvature variation {var:.3e} 1/mm^2");
    }
}
