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
                let d = s.derivatives(u, v, 1);
                let (su, sv) = (d[1][0], d[0][1]);
                let area = su.cross(&sv).norm() / (nu * nv) as f64;
                let c = s.curvature(u, v);
                let (e, ff, g) = (su.dot(&su), su.dot(&sv), sv.dot(&sv));
                let det = e * g - ff * ff;
                let mut dk2 = 0.0;
                for (which, t) in [(1, c.dir1), (2, c.dir2)] {
                    let (tu, tv) = (t.dot(&su), t.dot(&sv));
                    let a = (g * tu - ff * tv) / det;
                    let b = (e * tv - ff * tu) / det;
                    let (ua, va) = (u + 0.5 * a, (v + 0.5 * b).clamp(0.0, 1.0));
                    let (ub, vb) = (u - 0.5 * a, (v - 0.5 * b).clamp(0.0, 1.0));
                    let ds = (s.point(ua, va) - s.point(ub, vb)).norm();
                    let (ca, cb) = (s.curvature(ua, va), s.curvature(ub, vb));
                    let (ka, kb) = if which == 1 {
                        (ca.k1, cb.k1)
                    } else {
                        (ca.k2, cb.k2)
                    };
                    dk2 += ((ka - kb) / ds).powi(2);
                }
                cells[i / 8][j / 3] += dk2 * area;
                tot += dk2 * area;
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
