//! Where the blend's fill is unfair (diagnostic): the curvature variation of the fill per
//! cell of a coarse (u, v) grid on the RoundTip pair.
use footscan_last::blend::{self, BlendParams};
use footscan_last::join::study;
use std::path::PathBuf;

fn main() {
    let data = std::env::var_os("FOOTSCAN_DATA")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data"));
    let pairs = study::real_pairs(&data).unwrap();
    for pair in &pairs {
        let f = blend::fill(&pair.back, &pair.toe, &BlendParams::default()).unwrap();
        let s = &f.fill;
        let (nu, nv) = (96, 24);
        let mut cells = vec![vec![0.0f64; 8]; 12];
        let mut tot = 0.0;
        for i in 0..nu {
            let u = (i as f64 + 0.5) / nu as f64;
            for j in 0..nv {
                let v = (j as f64 + 0.5) / nv as f64;
                let du = 1.0 / nu as f64;
                let dv = 1.0 / nv as f64;
                let var = blend::fair::fairness_at(s, u, v, du, dv).0.unwrap_or(0.0);
                cells[i / 8][j / 3] += var;
                tot += var;
            }
        }
        println!(
            "{}: fill variation {tot:.3e}, by_curve {}, rows u (12), columns v (8, back to toe)",
            pair.name, f.by_curve
        );
        for (i, r) in cells.iter().enumerate() {
            let p = s.point((i as f64 * 8.0 + 4.0) / nu as f64, 0.5);
            print!("u {:>2} ({:6.1} {:6.1} {:6.1}):", i, p.x, p.y, p.z);
            for c in r {
                print!(" {:8.1e}", c);
            }
            println!();
        }
    }
}
