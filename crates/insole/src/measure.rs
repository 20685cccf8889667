//! Every parameter measured back on the output mesh: the top found by casting rays down onto
//! the mesh (never from the design's fields), compared with what was asked and with the
//! scanned plantar surface.

use crate::design::{Design, Plantar};
use crate::params::Length;
use footscan::cad::sample_height;
use footscan_geom::mesh::{Bvh, TriMesh};
use footscan_geom::{P2, P3, V3};
use serde::Serialize;

/// Bounds of the targets: parameters within 0.2 mm and 0.3 degrees, the top within
/// 0.3 mm of the plantar surface.
pub const MM_BOUND: f64 = 0.2;
pub const DEG_BOUND: f64 = 0.3;
pub const CONTACT_BOUND_MM: f64 = 0.3;
/// Largest slope of the sole (rise over run) counted as weight-bearing (about 11 degrees).
pub const WEIGHT_BEARING_SLOPE: f64 = 0.2;

/// One parameter: asked, measured on the mesh, and whether the difference is in bounds.
#[derive(Clone, Debug, Serialize)]
pub struct Check {
    pub name: String,
    pub unit: &'static str,
    pub asked: f64,
    pub measured: f64,
    pub error: f64,
    pub bound: f64,
    pub ok: bool,
}

impl Check {
    fn new(name: &str, unit: &'static str, asked: f64, measured: f64, bound: f64) -> Check {
        let error = measured - asked;
        Check {
            name: name.into(),
            unit,
            asked,
            measured,
            error,
            bound,
            ok: error.abs() <= bound,
        }
    }
}

/// What the mesh shows.
#[derive(Clone, Debug, Serialize)]
pub struct Measured {
    pub checks: Vec<Check>,
    /// Measured pad apex (foot frame, mm), when there is a pad.
    pub pad_apex_mm: Option<P2>,
    /// The thinnest place of the shell (mm) and where (foot frame), and its lower bound:
    /// base thickness less top cover less the first ray cut-out.
    pub min_thickness_mm: f64,
    pub min_thickness_at: P2,
    pub min_thickness_bound_mm: f64,
    /// The top (with its cover) against the scanned plantar surface raised by the base
    /// thickness, lift and posts, over the weight-bearing area outside the corrections:
    /// points compared, largest and RMS difference (mm).
    pub contact_points: usize,
    pub contact_max_mm: f64,
    pub contact_max_at: P2,
    pub contact_rms_mm: f64,
    pub ok: bool,
}

/// The mesh's top at (x, y) (foot frame), or None off the insole.
fn top(bvh: &Bvh, x: f64, y: f64) -> Option<f64> {
    // Rays on the mesh's grid lines (its vertices lie on whole millimetres, the heel centre
    // on the axis, y = 0) lie on bounding-box faces: geom's slab test takes them.
    bvh.ray_cast(&P3::new(x, y, 1000.0), &V3::new(0.0, 0.0, -1.0), 2000.0)
        .map(|h| h.point.z)
}

/// Measures `mesh` (the shell, foot frame) against `d` and the scan `p`.
pub fn measure_back(d: &Design, p: &Plantar, mesh: &TriMesh) -> Measured {
    let bvh = Bvh::new(mesh);
    let pr = &d.params;
    let cover = pr.top_cover_mm;
    // The scanned plantar surface at a foot-frame point, laid flat as the design lays it,
    // straight from the scan's height map.
    let plantar = |x: f64, y: f64| -> Option<f64> {
        let w = d.frame.to_world(footscan_geom::P2::new(x, y));
        let (i, j) = p.map.cell_of(w.x, w.y)?;
        if !p.map.get(i, j).is_finite() {
            return None;
        }
        sample_height(&p.map, w.x, w.y).map(|z| (z.max(0.0) - d.bottom_at(x)).max(0.0))
    };
    // The top above the seat plane: what the foot touches less the base, lift and posts.
    let above = |x: f64, y: f64| -> Option<f64> {
        top(&bvh, x, y).map(|z| {
            z + cover - pr.base_thickness_mm - d.lift(x) - d.rear_post(x, y) - d.fore_post(x, y)
        })
    };
    let mut checks = Vec::new();
    let hc = d.marks.heel_centre;

    // Thickness at the heel centre: the shell from the floor to its top.
    let t_hc = top(&bvh, hc.x, hc.y).unwrap_or(f64::NAN);
    let seat = plantar(hc.x, hc.y).unwrap_or(d.seat_mm);
    checks.push(Check::new(
        "thickness_at_heel_centre",
        "mm",
        pr.shell_mm() + d.lift(hc.x) + d.rear_post(hc.x, hc.y) + seat,
        t_hc,
        MM_BOUND,
    ));

    // Heel cup: the rim at the outline's rearmost point level with the heel centre, above
    // the heel centre's top (0.2 mm inside the outline, where the ray meets the top).
    if pr.heel_cup_depth_mm > 0.0 {
        let x_rim = rear_crossing(d, hc.y) + 0.2;
        let rim = top(&bvh, x_rim, hc.y).unwrap_or(f64::NAN) - d.rear_post(x_rim, hc.y);
        let seat_top = t_hc - d.rear_post(hc.x, hc.y);
        checks.push(Check::new(
            "heel_cup_depth",
            "mm",
            pr.heel_cup_depth_mm,
            rim - seat_top,
            // The rim point lies 0.2 mm inside the outline, where the cup's smoothstep is
            // short of its full height by 3 (0.2 / 12)^2 of the depth, and the mesh's
            // boundary chords cut the outline's corners by up to cell^2 / 8R.
            MM_BOUND,
        ));
    }

    // Arch height: the top above the seat plane at the arch point.
    let ap = d.marks.arch_point;
    checks.push(Check::new(
        "arch_height",
        "mm",
        d.arch_target_mm,
        above(ap.x, ap.y).unwrap_or(f64::NAN),
        MM_BOUND,
    ));

    // Posts: slope of (top - plantar) across the heel at the heel centre's station, and
    // across the forefoot at the heads' (or in front of the end of a 3/4 insole), fitted on
    // points outside the other corrections.
    let across = |x: f64, yc: f64, half: f64, sign: f64| -> Option<f64> {
        let (mut sy, mut sz, mut syy, mut syz, mut n) = (0.0, 0.0, 0.0, 0.0, 0.0);
        let steps = 40;
        for k in 0..=steps {
            let y = yc - half + 2.0 * half * k as f64 / steps as f64;
            if d.pad(x, y) > 0.0 || d.cutout(x, y) > 0.0 || d.cup_weight(x, y) > 0.0 {
                continue;
            }
            let (Some(t), Some(f)) = (top(&bvh, x, y), plantar(x, y)) else {
                continue;
            };
            let z = t - f - d.lift(x);
            let u = sign * (y - yc);
            sy += u;
            sz += z;
            syy += u * u;
            syz += u * z;
            n += 1.0;
        }
        if n < 5.0 {
            return None;
        }
        let slope = (n * syz - sy * sz) / (n * syy - sy * sy);
        Some(slope.atan().to_degrees())
    };
    let post_sign = |s| match s {
        crate::params::PostSide::Medial => d.medial,
        crate::params::PostSide::Lateral => -d.medial,
    };
    checks.push(Check::new(
        "rearfoot_post",
        "deg",
        pr.rearfoot_post_deg,
        across(
            hc.x,
            hc.y,
            0.35 * d.heel_width_mm,
            post_sign(pr.rearfoot_post_side),
        )
        .unwrap_or(f64::NAN),
        DEG_BOUND,
    ));
    let (m1, m5) = (d.marks.mt1_head, d.marks.mt5_head);
    let x_ff = match pr.length {
        Length::Full => 0.5 * (m1.x + m5.x),
        Length::ThreeQuarter => m1.x.min(m5.x) - pr.three_quarter_behind_mm - 8.0,
    };
    if pr.forefoot_post_deg > 0.0 {
        checks.push(Check::new(
            "forefoot_post",
            "deg",
            pr.forefoot_post_deg,
            across(
                x_ff,
                0.5 * (m1.y + m5.y),
                0.35 * d.ball_width_mm,
                post_sign(pr.forefoot_post_side),
            )
            .unwrap_or(f64::NAN),
            DEG_BOUND,
        ));
    }

    // Metatarsal pad: the apex of (top - plantar) near where it was asked, by a quadratic fit
    // over 6 mm around the highest sample.
    let mut pad_apex = None;
    if pr.met_pad_height_mm > 0.0 {
        let rel = |x: f64, y: f64| -> Option<f64> { Some(above(x, y)? - plantar(x, y)?) };
        let (px, py) = (d.pad_apex.x, d.pad_apex.y);
        let mut best = (f64::MIN, px, py);
        let s = 0.5;
        for a in -16..=16 {
            for b in -16..=16 {
                let (x, y) = (px + a as f64 * s, py + b as f64 * s);
                if let Some(z) = rel(x, y) {
                    if z > best.0 {
                        best = (z, x, y);
                    }
                }
            }
        }
        let (cx, cy) = (best.1, best.2);
        let mut rows = Vec::new();
        for a in -6..=6 {
            for b in -6..=6 {
                let (dx, dy) = (a as f64 * 0.5, b as f64 * 0.5);
                if let Some(z) = rel(cx + dx, cy + dy) {
                    rows.push(([1.0, dx, dy, dx * dx, dx * dy, dy * dy], z));
                }
            }
        }
        if let Some(c) = least_squares6(&rows) {
            // Stationary point of c0 + c1 x + c2 y + c3 x^2 + c4 xy + c5 y^2.
            let det = 4.0 * c[3] * c[5] - c[4] * c[4];
            if det.abs() > 1e-12 {
                let dx = (-2.0 * c[5] * c[1] + c[4] * c[2]) / det;
                let dy = (-2.0 * c[3] * c[2] + c[4] * c[1]) / det;
                let (ax, ay) = (cx + dx, cy + dy);
                let h =
                    c[0] + c[1] * dx + c[2] * dy + c[3] * dx * dx + c[4] * dx * dy + c[5] * dy * dy;
                pad_apex = Some(P2::new(ax, ay));
                let dist = (ax - px).hypot(ay - py);
                checks.push(Check::new("met_pad_apex_offset", "mm", 0.0, dist, MM_BOUND));
                checks.push(Check::new(
                    "met_pad_apex_behind_heads",
                    "mm",
                    pr.met_pad_behind_mm,
                    d.marks.mt3_head.x - ax,
                    MM_BOUND,
                ));
                checks.push(Check::new(
                    "met_pad_height",
                    "mm",
                    pr.met_pad_height_mm,
                    h,
                    MM_BOUND,
                ));
            }
        }
        if pad_apex.is_none() {
            checks.push(Check::new(
                "met_pad_height",
                "mm",
                pr.met_pad_height_mm,
                f64::NAN,
                MM_BOUND,
            ));
        }
    }

    // First ray cut-out: the top below the plantar surface under the first head, 8 mm in
    // from the medial border (the head's landmark is on the border).
    if pr.first_ray_cutout_mm > 0.0 {
        let (x, y) = (m1.x, m1.y - 8.0 * d.medial);
        let depth = match (above(x, y), plantar(x, y)) {
            (Some(a), Some(f)) => f - a,
            _ => f64::NAN,
        };
        checks.push(Check::new(
            "first_ray_cutout",
            "mm",
            pr.first_ray_cutout_mm,
            depth,
            MM_BOUND,
        ));
    }

    // Thinnest place: the lowest top vertex (the bottom is the plane z = 0).
    let (mut min_t, mut min_at) = (f64::MAX, P2::origin());
    for (k, v) in mesh.vertices.iter().enumerate() {
        // Top vertices are even in the outline solid; take any vertex above the floor.
        let _ = k;
        if v.z > 1e-9 && v.z < min_t {
            min_t = v.z;
            min_at = v.xy();
        }
    }
    let bound = pr.shell_mm() - pr.first_ray_cutout_mm;

    // The top against the plantar surface over the weight-bearing area: scanned cells at
    // least 3 mm inside the footprint (the margin plus 3 mm inside the outline), outside the heel cup, arch support, pad and cut-out.
    let (mut n, mut maxd, mut ss, mut max_at) = (0usize, 0.0f64, 0.0, P2::origin());
    let outline = d.outline_polygon();
    let step = 2.0;
    let (mut x, x_end) = (
        d.outline.iter().map(|q| q.x).fold(f64::MAX, f64::min),
        d.outline.iter().map(|q| q.x).fold(f64::MIN, f64::max),
    );
    let (y_lo, y_hi) = (
        d.outline.iter().map(|q| q.y).fold(f64::MAX, f64::min),
        d.outline.iter().map(|q| q.y).fold(f64::MIN, f64::max),
    );
    while x <= x_end {
        let mut y = y_lo;
        while y <= y_hi {
            let q = footscan_geom::P2::new(x, y);
            if outline.contains(&q) && outline.distance_to_boundary(&q) >= 3.0 && !d.corrected(x, y)
            {
                // Where the sole faces the glass: scanned 1 mm around, sloping under
                // WEIGHT_BEARING_SLOPE (a rim turning up into the foot's side is not
                // stood on, and a 1 mm mesh cannot follow its bend).
                let near = [(1.0, 0.0), (-1.0, 0.0), (0.0, 1.0), (0.0, -1.0)]
                    .map(|(dx, dy)| plantar(x + dx, y + dy));
                let facing = match near {
                    [Some(a), Some(b), Some(c), Some(e)] => {
                        (0.5 * (a - b)).hypot(0.5 * (c - e)) < WEIGHT_BEARING_SLOPE
                    }
                    _ => false,
                };
                if !facing {
                    y += step;
                    continue;
                }
                if let (Some(a), Some(f)) = (above(x, y), plantar(x, y)) {
                    let e = a - f;
                    n += 1;
                    if e.abs() > maxd {
                        maxd = e.abs();
                        max_at = P2::new(x, y);
                    }
                    ss += e * e;
                }
            }
            y += step;
        }
        x += step;
    }
    let rms = if n > 0 {
        (ss / n as f64).sqrt()
    } else {
        f64::NAN
    };
    let ok =
        checks.iter().all(|c| c.ok) && min_t >= bound - 1e-6 && n > 0 && maxd <= CONTACT_BOUND_MM;
    Measured {
        checks,
        pad_apex_mm: pad_apex,
        min_thickness_mm: min_t,
        min_thickness_at: min_at,
        min_thickness_bound_mm: bound,
        contact_points: n,
        contact_max_mm: maxd,
        contact_max_at: max_at,
        contact_rms_mm: rms,
        ok,
    }
}

/// x of the outline's rearmost crossing of the line y = `y`.
fn rear_crossing(d: &Design, y: f64) -> f64 {
    let o = &d.outline;
    let mut best = f64::MAX;
    for k in 0..o.len() {
        let (a, b) = (o[k], o[(k + 1) % o.len()]);
        if (a.y <= y) != (b.y <= y) {
            let t = (y - a.y) / (b.y - a.y);
            best = best.min(a.x + t * (b.x - a.x));
        }
    }
    best
}

/// Least squares for six unknowns by the normal equations (Gaussian elimination with
/// partial pivoting); None when singular.
fn least_squares6(rows: &[([f64; 6], f64)]) -> Option<[f64; 6]> {
    let mut a = [[0.0; 7]; 6];
    for (r, z) in rows {
        for i in 0..6 {
            for j in 0..6 {
                a[i][j] += r[i] * r[j];
            }
            a[i][6] += r[i] * z;
        }
    }
    for c in 0..6 {
        let p = (c..6).max_by(|&i, &j| a[i][c].abs().total_cmp(&a[j][c].abs()))?;
        if a[p][c].abs() < 1e-12 {
            return None;
        }
        a.swap(c, p);
        let pivot = a[c];
        for (r, row) in a.iter_mut().enumerate() {
            if r != c {
                let f = row[c] / pivot[c];
                for (x, p) in row.iter_mut().zip(pivot.iter()).skip(c) {
                    *x -= f * p;
                }
            }
        }
    }
    Some(std::array::from_fn(|i| a[i][6] / a[i][i]))
}
