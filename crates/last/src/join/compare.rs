//! The two joining methods side by side on the same lasts: the Gordon join ([`super`]) and
//! the blend of morph and extension ([`crate::blend`]), with the same placement and planes,
//! measured by the same seam figures, the same fairness integral over the piece between the
//! seams and the same deviation of the kept parts, so a last maker can choose from one table
//! (docs/method.md sections 11 and 12). Also the pictures that go with it: both methods'
//! zebra stripes in one picture, and the Gordon join's time against points per section.

use super::output::{self as jout, Tessellation};
use super::reference;
use super::seam::{Deviation, SeamMetrics};
use super::study::{self, Pair};
use super::{join, zebra, JoinParams};
use crate::blend::fair::{self, Functional};
use crate::blend::weight::Weight;
use crate::blend::{self, Blend, BlendError, BlendParams, Skin};
use crate::draw::{Canvas, View, BLACK, BLUE, GREEN, GREY, RED, WHITE};
use footscan_geom::mesh::TriMesh;
use footscan_geom::nurbs::NurbsSurface;
use footscan_geom::plane::Plane;
use footscan_geom::P3;
use image::Rgb;
use serde::Serialize;
use std::path::Path;
use std::time::Instant;

/// Half width of the band about each plane whose facet angles give the floor, mm.
pub const FACET_BAND_MM: f64 = 2.5;

/// One joining method with its settings.
#[derive(Debug, Clone, PartialEq)]
pub enum Method {
    /// The Gordon join at the paper's settings with this bundle angle.
    Gordon { angle_deg: f64 },
    /// The blend fill with this blending function and skin, at its defaults.
    Blend(Blend, Skin),
}

impl Method {
    pub fn name(&self) -> String {
        match self {
            Method::Gordon { angle_deg } => format!("gordon {angle_deg:.0} deg"),
            Method::Blend(b, Skin::One) => format!("blend {}", b.name()),
            Method::Blend(b, Skin::Pieces) => format!("blend {} pieces", b.name()),
        }
    }
}

/// The methods of the comparison: the Gordon join at the paper's 45 deg and at 10 deg, the
/// blend with the linear and polynomial functions and faired, the morph alone, and the
/// morph and the polynomial blend with each piece skinned apart (the seams then show what
/// the fill's slices carry: the morph's tangent break as the paper shows it).
pub fn methods() -> Vec<Method> {
    vec![
        Method::Gordon { angle_deg: 45.0 },
        Method::Gordon { angle_deg: 10.0 },
        Method::Blend(Blend::Fixed(Weight::Linear), Skin::One),
        Method::Blend(Blend::Fixed(Weight::Poly), Skin::One),
        Method::Blend(Blend::Fair(Functional::Variation), Skin::One),
        Method::Blend(Blend::Fixed(Weight::Morph), Skin::One),
        Method::Blend(Blend::Fixed(Weight::Poly), Skin::Pieces),
        Method::Blend(Blend::Fixed(Weight::Morph), Skin::Pieces),
    ]
}

/// The figures of one seam that the gates name.
#[derive(Debug, Clone, Copy, Serialize)]
pub struct Seam {
    pub gap_mm: f64,
    pub normal_max_deg: f64,
    pub normal_mean_deg: f64,
    pub curvature_rel_max: f64,
    pub curvature_rel_mean: f64,
}

impl From<&SeamMetrics> for Seam {
    fn from(m: &SeamMetrics) -> Seam {
        Seam {
            gap_mm: m.gap_max_mm,
            normal_max_deg: m.normal_max_deg,
            normal_mean_deg: m.normal_mean_deg,
            curvature_rel_max: m.curvature_rel_max,
            curvature_rel_mean: m.curvature_rel_mean,
        }
    }
}

/// One method on one pair.
#[derive(Debug, Clone, Serialize)]
pub struct Row {
    pub pair: String,
    pub method: String,
    /// Fastest of the repeats, ms: from the two meshes to the three surfaces.
    pub time_ms: f64,
    pub back_seam: Seam,
    pub toe_seam: Seam,
    /// The kept parts' ends against the original lasts at the planes
    /// ([`super::reference`]).
    pub back_original: Seam,
    pub toe_original: Seam,
    /// The original lasts' own facet angles across the planes, deg (max, mean): the floor of
    /// the figures against them ([`super::reference::facet_angles`]).
    pub back_facets_deg: (f64, f64),
    pub toe_facets_deg: (f64, f64),
    /// Integral of the squared principal-curvature variation over the piece between the
    /// seams (the Gordon join's patch, the blend's fill), 1/mm^2.
    pub fill_variation: f64,
    /// Worst of the two kept parts against their meshes, mm.
    pub fit_rms_mm: f64,
    pub fit_max_mm: f64,
    /// Fitting the kept parts to their meshes (back, toe), ms, and the fitted parts' largest
    /// distance from their meshes on the fit's own check grid (back, toe), mm; zero where
    /// the method does not fit them.
    pub fit_ms: (f64, f64),
    pub fit_check_max_mm: (f64, f64),
}

/// What the zebra picture of one result needs.
pub struct Picture {
    pub pair: String,
    pub method: String,
    pub tess: Tessellation,
    pub seams: Vec<Vec<P3>>,
    /// x range of the join region.
    pub clip: (f64, f64),
}

fn seam_curves(back: &NurbsSurface, toe: &NurbsSurface) -> Vec<Vec<P3>> {
    [(back, 1.0), (toe, 0.0)]
        .iter()
        .map(|(s, v)| (0..=200).map(|i| s.point(i as f64 / 200.0, *v)).collect())
        .collect()
}

/// Run every method on every pair (best time of `repeats`); with `pictures`, also the
/// tessellations for the zebra pictures.
pub fn run(
    pairs: &[Pair],
    methods: &[Method],
    repeats: usize,
    pictures: bool,
) -> Result<(Vec<Row>, Vec<Picture>), BlendError> {
    let mut rows = Vec::new();
    let mut pics = Vec::new();
    let best_of = |f: &mut dyn FnMut() -> Result<f64, BlendError>| -> Result<f64, BlendError> {
        let mut best = f64::INFINITY;
        for _ in 0..repeats.max(1) {
            best = best.min(f()?);
        }
        Ok(best)
    };
    for pair in pairs {
        for m in methods {
            let row_of = |time_ms: f64,
                          s: [&SeamMetrics; 4],
                          var: f64,
                          d: [&Deviation; 2],
                          o: [(&TriMesh, &Plane); 2]|
             -> Row {
                Row {
                    back_facets_deg: reference::facet_angles(o[0].0, o[0].1, FACET_BAND_MM),
                    toe_facets_deg: reference::facet_angles(o[1].0, o[1].1, FACET_BAND_MM),
                    pair: pair.name.clone(),
                    method: m.name(),
                    time_ms,
                    back_seam: s[0].into(),
                    toe_seam: s[1].into(),
                    back_original: s[2].into(),
                    toe_original: s[3].into(),
                    fill_variation: var,
                    fit_rms_mm: d[0].rms_mm.max(d[1].rms_mm),
                    fit_max_mm: d[0].max_mm.max(d[1].max_mm),
                    fit_ms: (0.0, 0.0),
                    fit_check_max_mm: (0.0, 0.0),
                }
            };
            match m {
                Method::Gordon { angle_deg } => {
                    let p = JoinParams {
                        angle_deg: *angle_deg,
                        fit_parts: true,
                        ..JoinParams::default()
                    };
                    // The join's own time without the fits of the kept parts (a cache per
                    // last could hold those; they are reported apart).
                    let j = join(&pair.back, &pair.toe, &p)?;
                    let mut time = j.timings.join;
                    for _ in 1..repeats.max(1) {
                        time = time.min(join(&pair.back, &pair.toe, &p)?.timings.join);
                    }
                    let q = jout::quality(&j, 400)?;
                    let (var, _) = fair::surface_fairness(&j.patch, 96, 24);
                    rows.push(row_of(
                        time,
                        [&q.back_seam, &q.toe_seam, &q.back_original, &q.toe_original],
                        var,
                        [&q.back_deviation, &q.toe_deviation],
                        [(&j.back_mesh, &j.back_plane), (&j.toe_mesh, &j.toe_plane)],
                    ));
                    if let (Some(f), Some(r)) = (&j.fits, rows.last_mut()) {
                        r.fit_ms = (f[0].ms, f[1].ms);
                        r.fit_check_max_mm = (f[0].max_mm, f[1].max_mm);
                    }
                    if pictures {
                        pics.push(Picture {
                            pair: pair.name.clone(),
                            method: m.name(),
                            tess: jout::tessellate(&j, 240, 1.0),
                            seams: seam_curves(&j.back, &j.toe),
                            clip: (j.back_plane.origin.x - 35.0, j.toe_plane.origin.x + 35.0),
                        });
                    }
                }
                Method::Blend(b, skin) => {
                    let p = BlendParams {
                        blend: b.clone(),
                        skin: *skin,
                        ..BlendParams::default()
                    };
                    let time = best_of(&mut || {
                        let t = Instant::now();
                        blend::fill(&pair.back, &pair.toe, &p)?;
                        Ok(t.elapsed().as_secs_f64() * 1e3)
                    })?;
                    let f = blend::fill(&pair.back, &pair.toe, &p)?;
                    let q = blend::output::quality(&f, 400)?;
                    rows.push(row_of(
                        time,
                        [&q.back_seam, &q.toe_seam, &q.back_original, &q.toe_original],
                        q.fill_variation,
                        [&q.back_deviation, &q.toe_deviation],
                        [(&f.back_mesh, &f.back_plane), (&f.toe_mesh, &f.toe_plane)],
                    ));
                    if pictures {
                        pics.push(Picture {
                            pair: pair.name.clone(),
                            method: m.name(),
                            tess: blend::output::tessellate(&f, 240, 1.0),
                            seams: seam_curves(&f.back, &f.toe),
                            clip: (
                                f.back_plane.origin.x - 35.0,
                                f.back_plane.origin.x + f.gap_mm + 35.0,
                            ),
                        });
                    }
                }
            }
        }
    }
    Ok((rows, pics))
}

/// The rows as one plain-text table: per seam the gap, the normal jump (max/mean) and the
/// relative curvature jump (max), then the same seam against the original last (normal
/// max/mean, relative curvature jump mean); the fill's curvature variation; the kept parts'
/// fit; time.
pub fn table(rows: &[Row]) -> String {
    let head = |a: [&str; 17]| {
        format!(
            "{:<24} {:<22} {:>6} | {:>7} {:>11} {:>7} | {:>7} {:>11} {:>7} | {:>11} {:>5} | {:>11} {:>5} | {:>9} | {:>5} {:>5} | {:>9}\n",
            a[0], a[1], a[2], a[3], a[4], a[5], a[6], a[7], a[8], a[9], a[10], a[11], a[12], a[13], a[14], a[15], a[16]
        )
    };
    let mut s = head([
        "pair",
        "method",
        "ms",
        "back gap",
        "normal deg",
        "curv",
        "toe gap",
        "normal deg",
        "curv",
        "back/orig",
        "curv",
        "toe/orig",
        "curv",
        "fill var",
        "fit",
        "fit",
        "fit parts",
    ]);
    s.push_str(&head([
        "", "", "", "mm", "max/mean", "max", "mm", "max/mean", "max", "deg", "mean", "deg", "mean",
        "1/mm^2", "rms", "max", "ms b/t",
    ]));
    let nm = |max: f64, mean: f64| {
        if max < 1e-3 {
            format!("{max:.0e}/{mean:.0e}")
        } else {
            format!("{max:.2}/{mean:.2}")
        }
    };
    for r in rows {
        s.push_str(&format!(
            "{:<24} {:<22} {:>6.1} | {:>7.0e} {:>11} {:>7.0e} | {:>7.0e} {:>11} {:>7.0e} | {:>11} {:>5.2} | {:>11} {:>5.2} | {:>9.3e} | {:>5.3} {:>5.3} | {:>9}\n",
            r.pair,
            r.method,
            r.time_ms,
            r.back_seam.gap_mm,
            nm(r.back_seam.normal_max_deg, r.back_seam.normal_mean_deg),
            r.back_seam.curvature_rel_max,
            r.toe_seam.gap_mm,
            nm(r.toe_seam.normal_max_deg, r.toe_seam.normal_mean_deg),
            r.toe_seam.curvature_rel_max,
            nm(r.back_original.normal_max_deg, r.back_original.normal_mean_deg),
            r.back_original.curvature_rel_mean,
            nm(r.toe_original.normal_max_deg, r.toe_original.normal_mean_deg),
            r.toe_original.curvature_rel_mean,
            r.fill_variation,
            r.fit_rms_mm,
            r.fit_max_mm,
            if r.fit_ms.0 > 0.0 {
                format!("{:.0}/{:.0}", r.fit_ms.0, r.fit_ms.1)
            } else {
                "-".into()
            }
        ));
    }
    let mut seen: Vec<&str> = Vec::new();
    for r in rows {
        if seen.contains(&r.pair.as_str()) {
            continue;
        }
        seen.push(&r.pair);
        s.push_str(&format!(
            "{}: the original lasts' facets meet at {:.1}/{:.1} deg (max/mean) within {} mm of \
             the back plane, {:.1}/{:.1} deg at the toe plane\n",
            r.pair,
            r.back_facets_deg.0,
            r.back_facets_deg.1,
            FACET_BAND_MM,
            r.toe_facets_deg.0,
            r.toe_facets_deg.1
        ));
    }
    s
}

/// DIR/zebra_PAIR.png for the pair named `pair`: its Gordon join at 45 deg (left) beside its
/// polynomial blend (right), from `pics` as [`run`] draws them. Returns the path written.
pub fn pair_zebra_png(
    dir: &Path,
    pair: &str,
    pics: &[Picture],
) -> std::io::Result<std::path::PathBuf> {
    let pick = |m: &str| {
        pics.iter()
            .find(|p| p.pair == pair && p.method == m)
            .ok_or_else(|| {
                std::io::Error::new(
                    std::io::ErrorKind::NotFound,
                    format!("no {m} picture of {pair}: run the Gordon 45 deg and poly blend rows"),
                )
            })
    };
    let slug = pair
        .split_whitespace()
        .next()
        .unwrap_or("pair")
        .to_lowercase();
    let path = dir.join(format!("zebra_{slug}.png"));
    let caption = format!("{pair}: Gordon join at 45 deg (left) and polynomial blend (right)");
    zebra_side_by_side_png(
        &path,
        [pick("gordon 45 deg")?, pick("blend poly")?],
        &caption,
    )?;
    Ok(path)
}

/// Zebra stripes of two results in one picture, left and right, each a top view over a side
/// view of the join region at one common scale, so stripes compare stripe for stripe.
pub fn zebra_side_by_side_png(
    path: &Path,
    pics: [&Picture; 2],
    caption: &str,
) -> std::io::Result<()> {
    let (w, h) = (1600u32, 920u32);
    let mut c = Canvas::new(w, h, WHITE);
    let col_w = w as f64 / 2.0;
    for (k, o) in [zebra::Ortho::top(), zebra::Ortho::side()]
        .iter()
        .enumerate()
    {
        // One scale for both columns: the union of their bounds.
        let b = pics.iter().map(|p| zebra::bounds(&p.tess, o, p.clip)).fold(
            [
                f64::INFINITY,
                f64::NEG_INFINITY,
                f64::INFINITY,
                f64::NEG_INFINITY,
            ],
            |a, b| {
                [
                    a[0].min(b[0]),
                    a[1].max(b[1]),
                    a[2].min(b[2]),
                    a[3].max(b[3]),
                ]
            },
        );
        let top = 60.0 + k as f64 * 430.0;
        for (i, p) in pics.iter().enumerate() {
            let left = i as f64 * col_w + 20.0;
            let view = View::fit(b, left, top + 400.0, col_w - 40.0, 390.0);
            zebra::render(&mut c, &view, o, &p.tess, p.clip, &|n, _, _| {
                zebra::stripe(n, 18.0)
            });
            zebra::seams(&mut c, &view, o, &p.seams);
            c.text(
                left as i64,
                top as i64 - 16,
                &format!("{}: {} view", p.method, o.title),
                BLACK,
                1,
            );
        }
    }
    c.text(20, 8, caption, BLACK, 1);
    c.text(
        20,
        24,
        "isophotes of one light direction; red: seams. A kink in the stripes at a seam: tangent break",
        BLACK,
        1,
    );
    c.save_png(path)
}

/// The Gordon join's time against points per section from the study rows (one line per pair)
/// beside the line through the origin and the time at 500 points (linear growth).
pub fn time_vs_points_png(path: &Path, rows: &[study::Row]) -> std::io::Result<()> {
    let (w, h) = (900u32, 620u32);
    let mut c = Canvas::new(w, h, WHITE);
    let base = study::Case {
        aux: 2,
        points: 500,
        angle_deg: 45.0,
    };
    let mut pairs: Vec<&str> = rows.iter().map(|r| r.pair.as_str()).collect();
    pairs.dedup();
    let series: Vec<(&str, Vec<(f64, f64)>)> = pairs
        .iter()
        .map(|p| {
            let mut v: Vec<(f64, f64)> = rows
                .iter()
                .filter(|r| r.pair == *p && r.aux == base.aux && r.angle_deg == base.angle_deg)
                .map(|r| (r.points as f64, r.time_ms))
                .collect();
            // The base case recurs in each sweep of the study: keep its fastest time.
            v.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.total_cmp(&b.1)));
            v.dedup_by(|a, b| a.0 == b.0);
            (*p, v)
        })
        .collect();
    let xmax = series
        .iter()
        .flat_map(|s| s.1.iter().map(|p| p.0))
        .fold(0.0, f64::max)
        .max(1.0);
    let ymax = series
        .iter()
        .flat_map(|s| s.1.iter().map(|p| p.1))
        .fold(0.0, f64::max)
        .max(1e-3)
        * 1.15;
    let (left, bottom, pw, ph) = (90.0, 540.0, 760.0, 460.0);
    let sx = pw / xmax;
    let sy = ph / ymax;
    let view = View {
        x0: 0.0,
        y0: 0.0,
        scale: 1.0,
        left,
        bottom,
    };
    let px = |x: f64, y: f64| view.px(x * sx, y * sy);
    c.line_px(px(0.0, 0.0), px(xmax, 0.0), BLACK, 1);
    c.line_px(px(0.0, 0.0), px(0.0, ymax), BLACK, 1);
    let ystep = [1.0, 2.0, 5.0, 10.0, 20.0, 50.0]
        .into_iter()
        .find(|s| ymax / s <= 8.0)
        .unwrap_or(100.0);
    let mut y = 0.0;
    while y <= ymax {
        let (a, b) = (px(0.0, y), px(xmax, y));
        c.line_px((a.0 - 5.0, a.1), a, BLACK, 1);
        c.line_px(a, b, Rgb([225, 225, 225]), 1);
        c.text(
            a.0 as i64 - 50,
            a.1 as i64 - 4,
            &format!("{y:>4.0}"),
            BLACK,
            1,
        );
        y += ystep;
    }
    let mut x = 0.0;
    while x <= xmax + 1e-9 {
        let a = px(x, 0.0);
        c.line_px(a, (a.0, a.1 + 5.0), BLACK, 1);
        c.text(
            a.0 as i64 - 12,
            a.1 as i64 + 10,
            &format!("{x:.0}"),
            BLACK,
            1,
        );
        x += 100.0;
    }
    let colours = [BLUE, GREEN, RED];
    for (k, (name, pts)) in series.iter().enumerate() {
        let col = colours[k % colours.len()];
        for seg in pts.windows(2) {
            c.line_px(px(seg[0].0, seg[0].1), px(seg[1].0, seg[1].1), col, 2);
        }
        for p in pts {
            let q = px(p.0, p.1);
            for d in -3..=3 {
                c.line_px(
                    (q.0 - 3.0, q.1 + d as f64),
                    (q.0 + 3.0, q.1 + d as f64),
                    col,
                    1,
                );
            }
        }
        // Linear growth through the origin and the 500-point time.
        if let Some(r) = pts.iter().find(|p| p.0 == base.points as f64) {
            let k_lin = r.1 / r.0;
            let end = (xmax, k_lin * xmax);
            let (a, b) = (px(0.0, 0.0), px(end.0, end.1.min(ymax)));
            let b = if end.1 > ymax {
                px(ymax / k_lin, ymax)
            } else {
                b
            };
            let n = 40;
            for i in (0..n).step_by(2) {
                let t0 = i as f64 / n as f64;
                let t1 = (i + 1) as f64 / n as f64;
                c.line_px(
                    (a.0 + (b.0 - a.0) * t0, a.1 + (b.1 - a.1) * t0),
                    (a.0 + (b.0 - a.0) * t1, a.1 + (b.1 - a.1) * t1),
                    col,
                    1,
                );
            }
        }
        c.text(
            120,
            70 + 16 * k as i64,
            &format!("{name}: measured (solid), linear through 500 points (dashed)"),
            col,
            1,
        );
    }
    c.text(
        20,
        12,
        "Gordon join: time (ms, best of the repeats, one core) against points per section",
        BLACK,
        1,
    );
    c.text(20, 28, "2 + 2 auxiliary sections, 45 deg", GREY, 1);
    c.text(
        (left + pw / 2.0) as i64 - 80,
        bottom as i64 + 34,
        "points per section",
        BLACK,
        1,
    );
    c.text(10, 50, "ms", BLACK, 1);
    c.save_png(path)
}

/// Our Gordon surface against OpenCASCADE's GeomFill_Gordon on the same network.
#[derive(Debug, Clone, Serialize)]
pub struct OcctRow {
    pub pair: String,
    pub sections: usize,
    pub guides: usize,
    /// Best of 5 builds of our surface, ms, and OCCT's build, ms.
    pub ours_ms: f64,
    pub occt_ms: f64,
    /// Largest distance between the two surfaces at equal parameters, mm, and of the network
    /// curves from OCCT's surface.
    pub same_param_max_mm: f64,
    pub network_to_occt_max_mm: f64,
}

/// Build our Gordon surface on the main and auxiliary sections of a join of `pair` (kept
/// parts sectioned every 5 mm, the network OCCT 8.0.1 builds; on the whole network of ~90
/// sections it gives up) and have `script` (scripts/occt_gordon_compare.py) run by `python`
/// build OCCT's on the same network and measure both. Fails naming the step.
pub fn occt_gordon(pair: &Pair, python: &Path, script: &Path) -> Result<OcctRow, String> {
    let p = JoinParams {
        part_step_mm: 5.0,
        fit_parts: false,
        ..JoinParams::default()
    };
    let j = join(&pair.back, &pair.toe, &p).map_err(|e| format!("{}: join: {e}", pair.name))?;
    let i_bm = j
        .section_info
        .iter()
        .rposition(|s| s.0 == super::Part::Back)
        .ok_or_else(|| format!("{}: no back section", pair.name))?;
    let range = i_bm - p.aux_back..i_bm + 1 + p.aux_toe + 1;
    let net = super::gordon::sub_network(&j.network, range)
        .map_err(|e| format!("{}: sub-network: {e}", pair.name))?;
    let mut best = f64::INFINITY;
    let mut g = None;
    for _ in 0..5 {
        let t = Instant::now();
        g = Some(
            super::gordon::gordon(&net, 1e-6)
                .map_err(|e| format!("{}: Gordon surface: {e}", pair.name))?,
        );
        best = best.min(t.elapsed().as_secs_f64() * 1e3);
    }
    let g = g.expect("five builds");
    let file = std::env::temp_dir().join(format!(
        "footscan-occt-net-{}-{}.json",
        std::process::id(),
        pair.name.split_whitespace().next().unwrap_or("pair")
    ));
    std::fs::write(&file, jout::network_json_of(&net, &g.surface, best))
        .map_err(|e| format!("writing {}: {e}", file.display()))?;
    let o = std::process::Command::new(python)
        .arg(script)
        .arg(&file)
        .output();
    let _ = std::fs::remove_file(&file);
    let o = o.map_err(|e| format!("running {}: {e}", python.display()))?;
    let out = String::from_utf8_lossy(&o.stdout).to_string();
    if !o.status.success() {
        return Err(format!(
            "{} failed: {out}{}",
            script.display(),
            String::from_utf8_lossy(&o.stderr)
        ));
    }
    let v: serde_json::Value = serde_json::from_str(out.lines().last().unwrap_or(""))
        .map_err(|e| format!("{}: no JSON answer ({e}): {out}", script.display()))?;
    if v["occt_done"] != true {
        return Err(format!(
            "{}: OCCT did not build the surface: {v}",
            pair.name
        ));
    }
    let f = |k: &str| v[k].as_f64().unwrap_or(f64::NAN);
    Ok(OcctRow {
        pair: pair.name.clone(),
        sections: net.sections.len(),
        guides: net.guides.len(),
        ours_ms: best,
        occt_ms: f("occt_ms"),
        same_param_max_mm: f("same_param_max"),
        network_to_occt_max_mm: f("network_to_occt_max"),
    })
}
