//! The printable scan report (issue 18): one PDF page with the foot's outline at 1:1 scale
//! (1 mm on paper is 1 mm of foot, heel point at the bottom, the foot axis up the page, seen
//! from above), a printed 100 mm calibration bar so a printout can be checked with a ruler,
//! and the measurements with their definitions and shoe sizes.
//!
//! Written with `pdf-writer` (the typst project's PDF writer) in PDF points (1/72 inch): every
//! length on the page is `mm * 72 / 25.4`, so the scale does not depend on a renderer's DPI.
//! Text uses the standard Helvetica font (no font file embedded).

use crate::scandata::ScanDir;
use anyhow::{bail, Context, Result};
use footscan_geom::{quarter_turn, P2};
use pdf_writer::{Content, Finish, Name, Pdf, Rect, Ref, Str};
use serde_json::Value;
use std::path::Path;

/// PDF points per millimetre.
pub const PT_PER_MM: f64 = 72.0 / 25.4;
/// Length of the printed calibration bar (mm).
pub const RULER_MM: f64 = 100.0;
/// The bar's fill colour (RGB 0-1): a colour nothing else on the page uses, so a test can find
/// the bar in a rendering.
pub const RULER_RGB: [f32; 3] = [0.0, 0.0, 0.8];
/// The foot-length line (heel point to toe tip) colour, likewise unique on the page.
pub const LENGTH_RGB: [f32; 3] = [0.85, 0.0, 0.0];
/// Toe allowance added to the foot length for the shoe sizes (the last is longer than the
/// foot).
pub const ALLOWANCE_MM: f64 = 15.0;

/// Shoe sizes from a foot length: Mondopoint (ISO 9407: the foot length in mm, rounded to
/// 5 mm), and the last-length systems from foot length + [`ALLOWANCE_MM`]: EU (Paris points
/// of 2/3 cm), UK (barleycorns of 1/3 inch from 25 for an adult's 0: 3 * inches - 25) and US
/// (men: UK + 1, women: UK + 2.5). Approximate: makers' allowances differ by a size.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ShoeSizes {
    pub mondopoint: f64,
    pub eu: f64,
    pub uk: f64,
    pub us_men: f64,
    pub us_women: f64,
}

pub fn shoe_sizes(foot_length_mm: f64) -> ShoeSizes {
    let last = foot_length_mm + ALLOWANCE_MM;
    let half = |x: f64| (x * 2.0).round() / 2.0;
    let uk = half(3.0 * last / 25.4 - 25.0);
    ShoeSizes {
        mondopoint: (foot_length_mm / 5.0).round() * 5.0,
        eu: (1.5 * last / 10.0).round(),
        uk,
        us_men: uk + 1.0,
        us_women: uk + 2.5,
    }
}

/// What the report shows, read from a scan directory.
pub struct ReportInput {
    pub title: String,
    /// measurements.json.
    pub measurements: Value,
    /// scan.json (verdict, frames); Null if absent.
    pub summary: Value,
    /// record.json of the daemon's archive (subject, side chosen, started); Null if absent.
    pub record: Value,
}

impl ReportInput {
    /// Read `dir`'s measurements.json (required: the report is about a measured foot),
    /// scan.json and record.json (optional).
    pub fn from_scan_dir(dir: &Path) -> Result<ReportInput> {
        let scan = ScanDir::new(dir);
        let read =
            |name: &str| -> Result<Option<Value>> { Ok(scan.load_json(name, "valid JSON")?) };
        let Some(measurements) = read(ScanDir::MEASUREMENTS)? else {
            bail!(
                "{}: no measurements.json: the report needs a scan whose foot was measured \
                 (a scan directory written by `footscan scan` or footscand with measure.foot)",
                dir.display()
            );
        };
        let title = dir
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        Ok(ReportInput {
            title,
            measurements,
            summary: read(ScanDir::SUMMARY)?.unwrap_or(Value::Null),
            record: read(ScanDir::RECORD)?.unwrap_or(Value::Null),
        })
    }
}

fn point(v: &Value) -> Option<P2> {
    Some(P2::new(v.get(0)?.as_f64()?, v.get(1)?.as_f64()?))
}

/// Text in the standard fonts' WinAnsi encoding (the few non-ASCII signs the report uses).
fn winansi(s: &str) -> Vec<u8> {
    s.chars()
        .map(|c| match c {
            ' '..='~' => c as u8,
            '°' => 0xB0,
            '²' => 0xB2,
            '±' => 0xB1,
            '–' => 0x96,
            '—' => 0x97,
            '·' => 0xB7,
            _ => b'?',
        })
        .collect()
}

/// A page being drawn in millimetres from its bottom-left corner.
struct Page {
    c: Content,
}

impl Page {
    fn text(&mut self, x_mm: f64, y_mm: f64, size: f32, bold: bool, s: &str) {
        let font = if bold { "F2" } else { "F1" };
        self.c.set_fill_rgb(0.0, 0.0, 0.0);
        self.c.begin_text();
        self.c.set_font(Name(font.as_bytes()), size);
        self.c.next_line(pt(x_mm), pt(y_mm));
        self.c.show(Str(&winansi(s)));
        self.c.end_text();
    }
    fn line(&mut self, a: P2, b: P2, width_mm: f64, rgb: [f32; 3]) {
        self.c.set_stroke_rgb(rgb[0], rgb[1], rgb[2]);
        self.c.set_line_width(pt(width_mm));
        self.c.move_to(pt(a.x), pt(a.y));
        self.c.line_to(pt(b.x), pt(b.y));
        self.c.stroke();
    }
    fn rect(&mut self, x: f64, y: f64, w: f64, h: f64, rgb: [f32; 3]) {
        self.c.set_fill_rgb(rgb[0], rgb[1], rgb[2]);
        self.c.rect(pt(x), pt(y), pt(w), pt(h));
        self.c.fill_nonzero();
    }
    fn dot(&mut self, p: P2, r_mm: f64, rgb: [f32; 3]) {
        self.rect(p.x - r_mm, p.y - r_mm, 2.0 * r_mm, 2.0 * r_mm, rgb);
    }
}

fn pt(mm: f64) -> f32 {
    (mm * PT_PER_MM) as f32
}

/// Where things are on the page (mm), for the tests.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Layout {
    /// Width and height (mm).
    pub page_mm: [f64; 2],
    /// The calibration bar (upright): x, y of its lower end, then its length (mm).
    pub ruler: [f64; 3],
    /// Heel point and toe tip on the page.
    pub heel: P2,
    pub toe: P2,
}

/// A measured foot in its own frame (mm): `a` along the axis from the heel point, `c` across
/// (+y of the scanner).
struct Foot {
    outlines: Vec<Vec<P2>>,
    length: f64,
    toe: P2,
    /// MT1 and MT5 heads.
    mt: Option<(P2, P2)>,
    a_min: f64,
    a_max: f64,
    c_min: f64,
    c_max: f64,
}

impl Foot {
    fn from_measurements(m: &Value) -> Result<Foot> {
        let need = |k: &str| {
            point(&m[k]).with_context(|| format!("measurements.json has no {k} (a point [x, y])"))
        };
        let heel = need("heel_point")?;
        let toe = need("toe_tip")?;
        let axis = need("axis_dir")?;
        let n = axis.coords.norm();
        if n.is_nan() || n <= 0.5 {
            bail!(
                "measurements.json: axis_dir {:?} is not a direction",
                [axis.x, axis.y]
            );
        }
        let axis = axis.coords / n;
        let length = m["foot_length_mm"]
            .as_f64()
            .context("measurements.json has no foot_length_mm")?;
        let local = |p: P2| {
            let d = p - heel;
            P2::new(d.dot(&axis), d.dot(&quarter_turn(&axis)))
        };
        // The sole's outline (a polygon) and the toe pads' (a list of polygons).
        let poly = |v: &Value| -> Vec<P2> {
            v.as_array()
                .map(|pts| pts.iter().filter_map(point).map(local).collect())
                .unwrap_or_default()
        };
        let mut outlines = vec![poly(&m["outline"])];
        if let Some(toes) = m["toe_outlines"].as_array() {
            outlines.extend(toes.iter().map(poly));
        }
        outlines.retain(|p| p.len() >= 3);
        if outlines.is_empty() {
            bail!("measurements.json has no outline (a polygon of [x, y] points)");
        }
        let (mut a_min, mut a_max, mut c_min, mut c_max) = (0.0f64, length, 0.0f64, 0.0f64);
        for p in outlines.iter().flatten() {
            a_min = a_min.min(p.x);
            a_max = a_max.max(p.x);
            c_min = c_min.min(p.y);
            c_max = c_max.max(p.y);
        }
        let mt = match (point(&m["mt1_head"]), point(&m["mt5_head"])) {
            (Some(a), Some(b)) => Some((local(a), local(b))),
            _ => None,
        };
        Ok(Foot {
            outlines,
            length,
            toe: local(toe),
            mt,
            a_min,
            a_max,
            c_min,
            c_max,
        })
    }

    fn width(&self) -> f64 {
        self.c_max - self.c_min
    }

    fn span(&self) -> f64 {
        self.a_max - self.a_min
    }

    /// The straight MT1-MT5 distance (mm): the last maker's ball width.
    fn straight_ball(&self) -> Option<f64> {
        self.mt
            .map(|(a, b)| ((a.x - b.x).powi(2) + (a.y - b.y).powi(2)).sqrt())
    }

    /// Draw at 1:1 with the outline's left edge at `left_x` and its rear at `bottom_y` (mm),
    /// seen from above with the toes up the page (+y of the scanner to the left). Returns the
    /// heel point and the end of the foot-length line on the page.
    fn draw(&self, pg: &mut Page, left_x: f64, bottom_y: f64) -> (P2, P2) {
        let cx = left_x + self.width() / 2.0;
        let c_mid = (self.c_max + self.c_min) / 2.0;
        let to_page = |p: P2| P2::new(cx - (p.y - c_mid), bottom_y - self.a_min + p.x);
        pg.c.set_stroke_rgb(0.1, 0.1, 0.1);
        pg.c.set_fill_rgb(0.93, 0.93, 0.93);
        pg.c.set_line_width(pt(0.3));
        for poly in &self.outlines {
            let f = to_page(poly[0]);
            pg.c.move_to(pt(f.x), pt(f.y));
            for p in &poly[1..] {
                let q = to_page(*p);
                pg.c.line_to(pt(q.x), pt(q.y));
            }
            pg.c.close_path();
            pg.c.fill_nonzero_and_stroke();
        }
        // Foot length: heel point to toe tip along the axis.
        let (h, t) = (to_page(P2::origin()), to_page(P2::new(self.length, 0.0)));
        pg.line(h, t, 0.5, LENGTH_RGB);
        for (p, label, dy) in [(h, "heel point", -4.0), (to_page(self.toe), "toe tip", 2.0)] {
            pg.dot(p, 1.0, LENGTH_RGB);
            pg.text(p.x + 2.0, p.y + dy, 7.0, false, label);
        }
        // Ball: MT1 and MT5 heads, joined straight.
        if let Some((a, b)) = self.mt {
            let (pa, pb) = (to_page(a), to_page(b));
            pg.line(pa, pb, 0.4, [0.0, 0.45, 0.0]);
            for (p, label) in [(pa, "MT1"), (pb, "MT5")] {
                pg.dot(p, 0.9, [0.0, 0.45, 0.0]);
                pg.text(p.x + 1.5, p.y + 1.5, 7.0, false, label);
            }
        }
        (h, t)
    }
}

/// The report as PDF bytes, and where its parts were put.
pub fn render(input: &ReportInput) -> Result<(Vec<u8>, Layout)> {
    let m = &input.measurements;
    let foot = Foot::from_measurements(m)?;
    let length = foot.length;
    let (c_min, c_max) = (foot.c_min, foot.c_max);
    // A4 portrait, A3 when the foot does not fit at 1:1 (header 25 mm, footer 12 mm).
    let span = foot.span();
    let page_mm = if span + 45.0 <= 297.0 {
        [210.0, 297.0]
    } else if span + 45.0 <= 420.0 {
        [297.0, 420.0]
    } else {
        bail!("the foot spans {span:.0} mm along its axis: more than an A3 page holds at 1:1");
    };
    let foot_cx = 12.0 + foot.width().max(90.0) / 2.0 + 2.0;
    let mut pg = Page { c: Content::new() };
    let (h, t) = foot.draw(&mut pg, foot_cx - foot.width() / 2.0, 14.0);
    let straight_ball = foot.straight_ball();

    // Header.
    // The record's side (the operator's, or as corrected), the scan's when there is none.
    let measured_side = m["side"].as_str().unwrap_or("?");
    let side = input.record["side"].as_str().unwrap_or(measured_side);
    let subject = input.record["subject"].as_str().unwrap_or("");
    let when = input.record["started"].as_str().unwrap_or("");
    let top = page_mm[1];
    let head = if subject.is_empty() {
        format!("footscan report: {side} foot")
    } else {
        format!("footscan report: {subject}, {side} foot")
    };
    pg.text(12.0, top - 12.0, 14.0, true, &head);
    let status = input.record["status"]
        .as_str()
        .or(input.summary["status"].as_str())
        .unwrap_or("?");
    let reason = input.record["reason"]
        .as_str()
        .or(input.summary["reason"].as_str());
    let mut sub = format!("scan {}", input.title);
    if !when.is_empty() {
        sub += &format!(", {when}");
    }
    sub += &format!(", verdict: {status}");
    if side != measured_side {
        sub += &format!(" (the scan looks like a {measured_side} foot)");
    }
    pg.text(12.0, top - 18.0, 8.0, false, &sub);
    if let Some(r) = reason {
        pg.text(12.0, top - 22.5, 7.0, false, &clip(r, 130));
    }

    // Measurements with definitions, in the column between the foot and the bar (about
    // 1.2 mm a character at 6.5 pt).
    let x0 = 128.0_f64.max(foot_cx + (c_max - c_min) / 2.0 + 6.0);
    let ruler_x = page_mm[0] - 14.0;
    let chars = ((ruler_x - 6.0 - x0) / 1.2) as usize;
    if chars < 30 {
        bail!(
            "the foot's outline is {:.0} mm wide: too wide for the report's layout (at most \
             about 130 mm)",
            c_max - c_min
        );
    }
    let mut y = top - 34.0;
    let num = |k: &str| m[k].as_f64();
    let mut row = |pg: &mut Page, label: &str, value: String, def: &str| {
        pg.text(x0, y, 9.0, true, &format!("{label}: {value}"));
        y -= 3.8;
        if def.is_empty() {
            return;
        }
        for l in wrap(def, chars) {
            pg.text(x0, y, 6.5, false, &l);
            y -= 2.9;
        }
        y -= 2.0;
    };
    row(
        &mut pg,
        "Foot length",
        format!("{length:.1} mm"),
        "heel point to toe tip along the foot axis (the red line)",
    );
    let s = shoe_sizes(length);
    row(
        &mut pg,
        "Shoe size",
        format!(
            "EU {:.0}, UK {:.1}, Mondopoint {:.0}",
            s.eu, s.uk, s.mondopoint
        ),
        "",
    );
    row(
        &mut pg,
        "US",
        format!("{:.1} men, {:.1} women", s.us_men, s.us_women),
        "Mondopoint: foot length in mm (ISO 9407); EU, UK, US from the last length = foot \
         length + 15 mm toe allowance (EU 2/3 cm steps, UK 3 x inches - 25, US men UK + 1, \
         women UK + 2.5); approximate: makers differ by about one size",
    );
    if let Some(b) = straight_ball {
        row(
            &mut pg,
            "Ball width, MT1-MT5",
            format!("{b:.1} mm"),
            "straight distance between the first and fifth metatarsal heads (the green line), \
             as last makers measure it",
        );
    }
    if let Some(b) = num("ball_width_mm") {
        row(
            &mut pg,
            "Ball width, across the axis",
            format!("{b:.1} mm"),
            "width of the footprint at the ball, square to the foot axis",
        );
    }
    if let Some(v) = num("midfoot_width_mm") {
        row(
            &mut pg,
            "Mid-foot width",
            format!("{v:.1} mm"),
            "width of the footprint at the waist, square to the foot axis",
        );
    }
    if let Some(v) = num("heel_width_mm") {
        row(
            &mut pg,
            "Heel width",
            format!("{v:.1} mm"),
            "widest footprint across the axis over the heel",
        );
    }
    if let Some(v) = num("arch_height_mm") {
        row(
            &mut pg,
            "Arch height",
            format!("{v:.1} mm"),
            "height of the medial arch above the glass at the arch point",
        );
    }
    if let Some(v) = num("arch_index") {
        let kind = if v < 0.21 {
            "high arch"
        } else if v <= 0.26 {
            "normal arch"
        } else {
            "flat arch"
        };
        row(
            &mut pg,
            "Arch index",
            format!("{v:.3} ({kind})"),
            "contact area of the middle third over the whole contact area without the toes \
             (Cavanagh and Rodgers 1987: < 0.21 high, 0.21-0.26 normal, > 0.26 flat)",
        );
    }
    if let Some(v) = num("axis_angle_deg") {
        row(
            &mut pg,
            "Axis angle",
            format!("{v:.1}°"),
            "foot axis (heel centre to MT2 head) against the scanner's travel",
        );
    }
    if let Some(v) = num("contact_area_mm2") {
        row(
            &mut pg,
            "Contact area",
            format!("{:.0} cm²", v / 100.0),
            "footprint on the glass",
        );
    }

    // Figures the measurement doubted: said on the page the clinic keeps, not only in JSON.
    let warnings: Vec<&str> = m["warnings"]
        .as_array()
        .map(|a| a.iter().filter_map(|w| w.as_str()).collect())
        .unwrap_or_default();
    if !warnings.is_empty() {
        y -= 2.0;
        pg.text(x0, y, 9.0, true, "Check these figures:");
        y -= 3.8;
        for (k, w) in warnings.iter().enumerate() {
            let lines = wrap(&format!("! {w}"), chars);
            // The ruler's caption takes the page's last 24 mm.
            if y - 2.9 * (lines.len() as f64) < 24.0 {
                let rest = warnings.len() - k;
                pg.text(
                    x0,
                    y,
                    6.5,
                    true,
                    &format!("... and {rest} more in measurements.json"),
                );
                break;
            }
            for l in lines {
                pg.text(x0, y, 6.5, false, &l);
                y -= 2.9;
            }
            y -= 1.0;
        }
    }

    let (rx, ry) = (ruler_x, 16.0);
    draw_ruler(&mut pg, rx, ry, x0, chars);
    let layout = Layout {
        page_mm,
        ruler: [rx, ry, RULER_MM],
        heel: h,
        toe: t,
    };
    Ok((pdf_page(page_mm, pg), layout))
}

/// The calibration bar: 100 mm upright with its lower end at (rx, ry), mm ticks, cm numbered;
/// its caption at x0 at the page's foot, wrapped at `chars`.
fn draw_ruler(pg: &mut Page, rx: f64, ry: f64, x0: f64, chars: usize) {
    pg.rect(rx, ry, 2.5, RULER_MM, RULER_RGB);
    for k in 0..=(RULER_MM as usize) {
        let y = ry + k as f64;
        let h = if k % 10 == 0 {
            4.0
        } else if k % 5 == 0 {
            3.0
        } else {
            1.8
        };
        pg.line(P2::new(rx - h, y), P2::new(rx, y), 0.12, [0.0, 0.0, 0.0]);
        if k % 10 == 0 {
            pg.text(rx + 3.5, y - 1.0, 6.0, false, &format!("{}", k / 10));
        }
    }
    pg.text(
        x0,
        12.0,
        8.0,
        true,
        "The blue bar (right) is 100 mm long: scale 1:1.",
    );
    for (k, l) in wrap(
        "Print at 100 % (\"actual size\", not \"fit to page\") and check the bar with a ruler \
         before using the outline.",
        chars,
    )
    .iter()
    .enumerate()
    {
        pg.text(x0, 8.5 - 2.9 * k as f64, 6.5, false, l);
    }
}

/// One page of `page_mm` holding `pg`, as a PDF.
fn pdf_page(page_mm: [f64; 2], pg: Page) -> Vec<u8> {
    let mut pdf = Pdf::new();
    let (catalog, tree, page, content, f1, f2) = (
        Ref::new(1),
        Ref::new(2),
        Ref::new(3),
        Ref::new(4),
        Ref::new(5),
        Ref::new(6),
    );
    pdf.catalog(catalog).pages(tree);
    pdf.pages(tree).kids([page]).count(1);
    let mut p = pdf.page(page);
    p.media_box(Rect::new(0.0, 0.0, pt(page_mm[0]), pt(page_mm[1])));
    p.parent(tree);
    p.contents(content);
    {
        let mut res = p.resources();
        let mut fonts = res.fonts();
        fonts.pair(Name(b"F1"), f1);
        fonts.pair(Name(b"F2"), f2);
    }
    p.finish();
    for (r, name) in [(f1, "Helvetica"), (f2, "Helvetica-Bold")] {
        pdf.type1_font(r)
            .base_font(Name(name.as_bytes()))
            .encoding_predefined(Name(b"WinAnsiEncoding"));
    }
    pdf.stream(content, &pg.c.finish());
    pdf.finish()
}

/// A visit's report: both feet side by side at 1:1 on an A3 landscape page (the left foot on
/// the left, as seen from above), the calibration bar, and a table of both feet's
/// measurements with the difference right minus left. `left` and `right` are the two scans'
/// inputs; `title` names the visit (patient, date).
pub fn render_visit(title: &str, left: &ReportInput, right: &ReportInput) -> Result<Vec<u8>> {
    let page_mm = [420.0, 297.0];
    let feet = [
        Foot::from_measurements(&left.measurements).context("the left foot")?,
        Foot::from_measurements(&right.measurements).context("the right foot")?,
    ];
    for (f, side) in feet.iter().zip(["left", "right"]) {
        if f.span() + 45.0 > page_mm[1] {
            bail!(
                "the {side} foot spans {:.0} mm along its axis: more than the page holds at 1:1",
                f.span()
            );
        }
    }
    let mut pg = Page { c: Content::new() };
    let mut x = 12.0;
    for f in &feet {
        f.draw(&mut pg, x, 14.0);
        x += f.width() + 12.0;
    }
    let x0 = x + 4.0;
    let ruler_x = page_mm[0] - 14.0;
    let chars = ((ruler_x - 6.0 - x0) / 1.2) as usize;
    if chars < 40 {
        bail!("the feet are too wide for the visit report's layout");
    }
    let top = page_mm[1];
    pg.text(
        12.0,
        top - 12.0,
        14.0,
        true,
        &format!("footscan visit report: {title}"),
    );
    pg.text(
        12.0,
        top - 18.0,
        8.0,
        false,
        "left foot | right foot, seen from above, 1:1",
    );
    // The table: measure, left, right, right - left.
    let cols = [x0, x0 + 58.0, x0 + 82.0, x0 + 106.0];
    let mut y = top - 34.0;
    for (c, h) in cols.iter().zip(["", "left", "right", "R - L"]) {
        pg.text(*c, y, 9.0, true, h);
    }
    y -= 5.0;
    let num = |i: &ReportInput, k: &str| i.measurements[k].as_f64();
    let rows: Vec<(&str, [Option<f64>; 2], usize)> = vec![
        (
            "Foot length (mm)",
            [Some(feet[0].length), Some(feet[1].length)],
            1,
        ),
        (
            "Ball width MT1-MT5 (mm)",
            [feet[0].straight_ball(), feet[1].straight_ball()],
            1,
        ),
        (
            "Ball width, across axis (mm)",
            [num(left, "ball_width_mm"), num(right, "ball_width_mm")],
            1,
        ),
        (
            "Mid-foot width (mm)",
            [
                num(left, "midfoot_width_mm"),
                num(right, "midfoot_width_mm"),
            ],
            1,
        ),
        (
            "Heel width (mm)",
            [num(left, "heel_width_mm"), num(right, "heel_width_mm")],
            1,
        ),
        (
            "Arch height (mm)",
            [num(left, "arch_height_mm"), num(right, "arch_height_mm")],
            1,
        ),
        (
            "Arch index",
            [num(left, "arch_index"), num(right, "arch_index")],
            3,
        ),
        (
            "Axis angle (°)",
            [num(left, "axis_angle_deg"), num(right, "axis_angle_deg")],
            1,
        ),
    ];
    let f = |v: Option<f64>, d: usize| v.map_or("-".to_string(), |v| format!("{v:.d$}"));
    for (label, v, d) in rows {
        pg.text(cols[0], y, 8.5, false, label);
        pg.text(cols[1], y, 8.5, false, &f(v[0], d));
        pg.text(cols[2], y, 8.5, false, &f(v[1], d));
        let diff = v[0].zip(v[1]).map(|(l, r)| r - l);
        pg.text(cols[3], y, 8.5, false, &f(diff, d));
        y -= 4.2;
    }
    let sizes = [shoe_sizes(feet[0].length), shoe_sizes(feet[1].length)];
    for (label, a, b) in [
        ("Shoe size EU", sizes[0].eu, sizes[1].eu),
        ("Shoe size UK", sizes[0].uk, sizes[1].uk),
        ("Mondopoint", sizes[0].mondopoint, sizes[1].mondopoint),
    ] {
        pg.text(cols[0], y, 8.5, false, label);
        pg.text(cols[1], y, 8.5, false, &format!("{a}"));
        pg.text(cols[2], y, 8.5, false, &format!("{b}"));
        y -= 4.2;
    }
    let verdict = |i: &ReportInput| {
        i.record["status"]
            .as_str()
            .or(i.summary["status"].as_str())
            .unwrap_or("?")
            .to_string()
    };
    pg.text(cols[0], y, 8.5, false, "Verdict");
    pg.text(cols[1], y, 7.0, false, &verdict(left));
    pg.text(cols[2], y, 7.0, false, &verdict(right));
    y -= 8.0;
    for l in wrap(
        "Foot length: heel point to toe tip along the foot axis (red). Ball width MT1-MT5: the \
         straight distance between the first and fifth metatarsal heads (green), as last makers \
         measure it; across the axis: the footprint's width at the ball square to the axis. \
         Arch index: contact area of the middle third over the whole without the toes (< 0.21 \
         high, 0.21-0.26 normal, > 0.26 flat). Shoe sizes from foot length + 15 mm (EU 2/3 cm, \
         UK 3 x inches - 25); Mondopoint = foot length (ISO 9407). Approximate: makers differ \
         by about one size.",
        chars,
    ) {
        pg.text(x0, y, 6.5, false, &l);
        y -= 2.9;
    }
    draw_ruler(&mut pg, ruler_x, 16.0, x0, chars);
    Ok(pdf_page(page_mm, pg))
}

fn clip(s: &str, n: usize) -> String {
    if s.chars().count() <= n {
        s.to_string()
    } else {
        format!("{}...", s.chars().take(n - 3).collect::<String>())
    }
}

fn wrap(s: &str, width: usize) -> Vec<String> {
    let mut lines = vec![String::new()];
    for w in s.split_whitespace() {
        let last = lines.last_mut().unwrap();
        if !last.is_empty() && last.len() + 1 + w.len() > width {
            lines.push(w.to_string());
        } else {
            if !last.is_empty() {
                last.push(' ');
            }
            last.push_str(w);
        }
    }
    lines
}

/// Write the report of scan directory `dir` to `out` (atomically).
pub fn write_report(dir: &Path, out: &Path) -> Result<Layout> {
    let input = ReportInput::from_scan_dir(dir)?;
    let (bytes, layout) = render(&input)?;
    footscan_util::write_atomic(out, &bytes)
        .with_context(|| format!("writing {}", out.display()))?;
    Ok(layout)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shoe_sizes_of_common_feet() {
        // 250 mm: EU 40, UK 6.5, US men 7.5 in the usual tables.
        let s = shoe_sizes(250.0);
        assert_eq!(
            (s.eu, s.uk, s.us_men, s.mondopoint),
            (40.0, 6.5, 7.5, 250.0)
        );
        let s = shoe_sizes(270.0);
        assert_eq!((s.eu, s.uk, s.mondopoint), (43.0, 8.5, 270.0));
    }

    #[test]
    fn text_is_winansi() {
        assert_eq!(winansi("1.5° ²x→"), b"1.5\xB0 \xB2x?".to_vec());
    }
}
