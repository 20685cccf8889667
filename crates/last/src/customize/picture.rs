//! The customization picture: side and top views of foot and last with the characteristic
//! curves and the rule table.

use super::Customized;
use crate::draw::{Canvas, View, AMBER, BLACK, BLUE, GREEN, GREY, RED, WHITE};
use footscan_geom::plane::Plane;
use footscan_geom::{P3, V3};
use std::path::Path;

fn outline(
    m: &footscan_geom::mesh::TriMesh,
    plane: &Plane,
    proj: impl Fn(&P3) -> (f64, f64),
) -> Vec<Vec<(f64, f64)>> {
    m.section(plane)
        .iter()
        .map(|l| l.points.iter().map(&proj).collect())
        .collect()
}

pub fn draw(c: &Customized, path: &Path) -> std::io::Result<()> {
    let (w, h) = (1400u32, 1000u32);
    let mut cv = Canvas::new(w, h, WHITE);
    let bb = c.last.bbox();
    let fb = c.foot.bbox();
    let xmin = bb.min.x.min(fb.min.x) - 5.0;
    let xmax = bb.max.x.max(fb.max.x) + 5.0;
    // Side view (x, z): the sagittal sections of foot and last, and the deformed profile.
    let side = View::fit(
        [xmin, xmax, -5.0, bb.max.z.max(90.0) + 5.0],
        20.0,
        420.0,
        900.0,
        380.0,
    );
    let sag = Plane::with_axis(P3::origin(), V3::y(), V3::x()).unwrap();
    for l in outline(&c.foot, &sag, |p| (p.x, p.z)) {
        cv.polyline(&side, &l, true, GREY, 1);
    }
    for l in outline(&c.last, &sag, |p| (p.x, p.z)) {
        cv.polyline(&side, &l, true, BLACK, 2);
    }
    // Top view (x, y): sole outlines of foot and last at 1.5 mm, and the plan curves.
    let top = View::fit(
        [
            xmin,
            xmax,
            bb.min.y.min(fb.min.y) - 5.0,
            bb.max.y.max(fb.max.y) + 5.0,
        ],
        20.0,
        960.0,
        900.0,
        500.0,
    );
    let pz = Plane::axis_aligned(2, super::measure::OUTLINE_Z);
    for l in outline(&c.foot, &pz, |p| (p.x, p.y)) {
        cv.polyline(&top, &l, true, GREY, 1);
    }
    // The last's outline as its rules were measured: laid flat by its bottom curve, if it
    // has one (a cut of the raised last at 1.5 mm misses the raised waist).
    // The clinic path holds the footprint against the last's plan outline: that is drawn
    // black, the 1.5 mm bottom grey.
    let clinic = !c.footprint.is_empty();
    for l in &c.last_measures.outline {
        let l: Vec<(f64, f64)> = l.iter().map(|p| (p.x, p.y)).collect();
        cv.polyline(
            &top,
            &l,
            true,
            if clinic { GREY } else { BLACK },
            if clinic { 1 } else { 2 },
        );
    }
    if clinic {
        let plan =
            super::measure::PlanProfile::new(&c.last, super::measure::PLAN_STEP, f64::INFINITY);
        let l: Vec<(f64, f64)> = plan.outline().iter().map(|p| (p.x, p.y)).collect();
        cv.polyline(&top, &l, true, BLACK, 2);
    }
    for l in &c.footprint {
        let l: Vec<(f64, f64)> = l.iter().map(|p| (p[0], p[1])).collect();
        cv.polyline(&top, &l, true, BLUE, 1);
    }
    for (i, (_, k)) in c.curves.last.iter().enumerate() {
        let pts: Vec<P3> = (0..=400).map(|j| k.point(j as f64 / 400.0)).collect();
        let col = [RED, BLUE, BLUE, BLUE, GREEN, RED][i];
        let s: Vec<(f64, f64)> = pts.iter().map(|p| (p.x, p.z)).collect();
        if i > 0 {
            cv.polyline(&side, &s, false, col, 1);
        }
        if i == 0 {
            let t: Vec<(f64, f64)> = pts.iter().map(|p| (p.x, p.y)).collect();
            cv.polyline(&top, &t, false, col, 1);
        }
    }
    let m = &c.foot_measures;
    for (n, p) in [
        ("O", m.o),
        ("A", m.a),
        ("P", m.p),
        ("B", m.b),
        ("C", m.c),
        ("D", m.d),
        ("E", m.e),
    ] {
        cv.dot(&top, (p.x, p.y), 4, RED);
        let (px, py) = top.px(p.x, p.y);
        cv.text(px as i64 + 6, py as i64 - 4, n, RED, 2);
    }
    cv.text(
        20,
        14,
        // The clinic path has no foot mesh: the grey one is the stock last.
        if c.footprint.is_empty() && c.clearance.of == "foot" {
            "side: foot grey, last black, last frame curves coloured"
        } else {
            "side: stock last grey, last black, last frame curves coloured"
        },
        BLACK,
        2,
    );
    cv.text(
        20,
        450,
        if c.footprint.is_empty() {
            "top: sole outlines at 1.5 mm (last laid flat), points O A P B C D E"
        } else {
            "top: last's plan outline black (bottom at 1.5 mm grey), footprint as set in it blue"
        },
        BLACK,
        2,
    );
    let mut y = 40;
    cv.text(900, y, "rule    foot  target   last", BLACK, 2);
    for r in &c.rules {
        y += 24;
        // A measure the build-up for the footprint grew is marked "b" (amber): met by the
        // solve, grown after it.
        let (mark, colour) = match (r.met, r.built_up_mm != 0.0, r.applies) {
            (_, _, false) => (" n/a", GREY),
            (true, false, true) => ("", GREEN),
            (true, true, true) => (" b", AMBER),
            (false, _, true) => ("", RED),
        };
        let s = format!(
            "{:<5}{:7.1} {:7.1}{:7.1}{mark}",
            r.rule, r.foot_mm, r.target_mm, r.last_mm
        );
        cv.text(900, y, &s, colour, 2);
    }
    y += 34;
    cv.text(
        900,
        y,
        &format!("clearance ({}), mm", c.clearance.of),
        BLACK,
        2,
    );
    for r in c.clearance.regions.iter().filter(|r| r.vertices > 0) {
        y += 24;
        let s = format!("{:<15}{:+6.1}", r.region, r.min_mm);
        let colour = match r.allowed_press_mm {
            None => GREY,
            Some(_) if r.met() => GREEN,
            Some(_) => RED,
        };
        cv.text(900, y, &s, colour, 2);
    }
    cv.save_png(path)
}
