//! Grading a last into a size run (docs/method.md 9.4): every size of the run made from one
//! last by the steps of a sizing system, each graded last measured again on its own
//! (`measure_last`) and the achieved steps tabled against the rule.
//!
//! Steps per size: Paris point 20/3 mm of length and 5 mm of joint girth; UK and US 1/3 inch
//! (8.467 mm) and 1/4 inch (6.35 mm); Mondopoint 5 mm of length (sizes are foot lengths in
//! mm, run in 5 mm steps) and the girth step proportionate, 5 mm times the base last's joint
//! girth over its stick length. A width fitting is one girth step with no length change.
//!
//! Arithmetic mode: the length and the joint girth each change by their step; x (along the
//! last) is scaled by one factor and y and z (across) by another, both solved until the
//! measured stick length and joint girth are the targets. Geometric mode: one factor for all
//! three axes, solved on the stick length (everything proportional). In both modes the
//! bottom's profile keeps its heights at the same fraction of the length: the heel height and
//! the toe spring stay those of the base last through the run.

use crate::measure_last::{measure_last, LastMeasures, MeasureError};
use crate::size::SIZE_GROUP;
use footscan_geom::export::step::Document;
use footscan_geom::export::{real, Header};
use footscan_geom::mesh::{Format, TriMesh};
use footscan_geom::P3;
use serde::Serialize;
use std::path::{Path, PathBuf};

/// Steps within these of the rule pass (mm): stick length, joint girth.
pub const LENGTH_TOL_MM: f64 = 0.2;
pub const GIRTH_TOL_MM: f64 = 0.5;

#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum System {
    Paris,
    Uk,
    Us,
    Mondopoint,
}

/// A sizing system or grading mode name that is not one.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum NameError {
    #[error("{0:?}: a sizing system is paris, uk, us or mondopoint")]
    System(String),
    #[error("{0:?}: a grading mode is arithmetic or geometric")]
    Mode(String),
}

impl std::str::FromStr for System {
    type Err = NameError;
    fn from_str(s: &str) -> Result<System, NameError> {
        match s.to_ascii_lowercase().as_str() {
            "paris" | "eu" | "french" => Ok(System::Paris),
            "uk" | "english" => Ok(System::Uk),
            "us" => Ok(System::Us),
            "mondopoint" | "mondo" => Ok(System::Mondopoint),
            _ => Err(NameError::System(s.to_string())),
        }
    }
}

impl System {
    /// Length change per size unit (mm): a Paris point, a third of an inch, a millimetre of
    /// Mondopoint.
    pub fn length_per_unit(self) -> f64 {
        match self {
            System::Paris => 20.0 / 3.0,
            System::Uk | System::Us => 25.4 / 3.0,
            System::Mondopoint => 1.0,
        }
    }
    /// The run's step between neighbouring sizes (size units) and the finest size allowed.
    pub fn size_step(self) -> f64 {
        match self {
            System::Mondopoint => 5.0,
            _ => 1.0,
        }
    }
    fn finest(self) -> f64 {
        match self {
            System::Mondopoint => 5.0,
            _ => 0.5,
        }
    }
    /// Sizes of the system this command grades (adult and children's Paris, adult UK and US
    /// men's, Mondopoint foot lengths).
    pub fn range(self) -> (f64, f64) {
        match self {
            System::Paris => (15.0, 52.0),
            System::Uk => (1.0, 15.0),
            System::Us => (1.0, 16.0),
            System::Mondopoint => (100.0, 350.0),
        }
    }
    /// The last length a size stands for (mm): Paris size x 20/3 mm; UK (size + 25)/3 inch;
    /// US men's (size + 24)/3 inch; Mondopoint the foot length plus 10 mm (a toe allowance of
    /// about 15 less a heel allowance of about 5, config/last-rules.toml).
    pub fn last_length(self, size: f64) -> f64 {
        match self {
            System::Paris => size * 20.0 / 3.0,
            System::Uk => (size + 25.0) * 25.4 / 3.0,
            System::Us => (size + 24.0) * 25.4 / 3.0,
            System::Mondopoint => size + 10.0,
        }
    }
    /// Joint girth change per size unit for the arithmetic rule (mm), given the base last.
    fn girth_per_unit(self, base: &LastMeasures) -> f64 {
        match self {
            System::Paris => 5.0,
            System::Uk | System::Us => 6.35,
            System::Mondopoint => base.joint_girth / base.stick_length,
        }
    }
    /// Joint girth change per width fitting (mm).
    fn girth_per_fitting(self, base: &LastMeasures) -> f64 {
        self.girth_per_unit(base) * self.size_step()
    }
    fn name(self) -> &'static str {
        match self {
            System::Paris => "Paris",
            System::Uk => "UK",
            System::Us => "US",
            System::Mondopoint => "Mondopoint",
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Mode {
    Arithmetic,
    Geometric,
}

impl std::str::FromStr for Mode {
    type Err = NameError;
    fn from_str(s: &str) -> Result<Mode, NameError> {
        match s {
            "arithmetic" => Ok(Mode::Arithmetic),
            "geometric" => Ok(Mode::Geometric),
            _ => Err(NameError::Mode(s.to_string())),
        }
    }
}

/// One width fitting: its label and its offset from the base last's fitting (fittings).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Width {
    pub label: String,
    pub offset: f64,
}

#[derive(Debug, thiserror::Error)]
pub enum GradeError {
    #[error("{0}")]
    Input(String),
    #[error(transparent)]
    Measure(#[from] MeasureError),
    #[error("{path}: {why}")]
    Output { path: String, why: String },
}

const LETTERS: &str = "ABCDEFGH";

/// Parses `--sizes`: a range `38-46` (every size step: 1, Mondopoint 5) or a list `38,39.5`;
/// every size on the system's grid (half sizes; Mondopoint 5 mm) and inside its range.
pub fn parse_sizes(s: &str, sys: System) -> Result<Vec<f64>, GradeError> {
    let bad = |why: String| GradeError::Input(format!("--sizes {s}: {why}"));
    let num = |t: &str| -> Result<f64, GradeError> {
        t.trim()
            .parse::<f64>()
            .map_err(|e| bad(format!("{t:?}: {e}")))
    };
    let mut sizes = Vec::new();
    if let Some((a, b)) = s.split_once('-').filter(|(a, _)| !a.trim().is_empty()) {
        let (a, b) = (num(a)?, num(b)?);
        if b < a {
            return Err(bad(format!("the range runs backwards ({a} to {b})")));
        }
        let n = ((b - a) / sys.size_step() + 1e-9).floor() as usize;
        sizes.extend((0..=n).map(|k| a + k as f64 * sys.size_step()));
    } else {
        for t in s.split(',') {
            sizes.push(num(t)?);
        }
    }
    let (lo, hi) = sys.range();
    for &z in &sizes {
        if !(lo..=hi).contains(&z) {
            return Err(bad(format!(
                "size {z} is outside the {} sizes this grades ({lo}-{hi})",
                sys.name()
            )));
        }
        let q = z / sys.finest();
        if (q - q.round()).abs() > 1e-6 {
            return Err(bad(format!(
                "size {z} is not a {} size (steps of {})",
                sys.name(),
                sys.finest()
            )));
        }
    }
    sizes.sort_by(f64::total_cmp);
    sizes.dedup();
    if sizes.is_empty() {
        return Err(bad("no sizes".into()));
    }
    Ok(sizes)
}

/// Parses `--widths`: letters A-H (UK, US; one fitting apart each, the base last being
/// `from_width`) or signed fitting offsets (-1,0,1) for any system.
pub fn parse_widths(s: &str, from_width: &str) -> Result<Vec<Width>, GradeError> {
    let bad = |why: String| GradeError::Input(format!("--widths {s}: {why}"));
    let letter = |t: &str| {
        let t = t.trim().to_ascii_uppercase();
        (t.len() == 1).then(|| LETTERS.find(&t)).flatten()
    };
    let mut out: Vec<Width> = Vec::new();
    for t in s.split(',') {
        let t = t.trim();
        let offset = if let Some(k) = letter(t) {
            let base = letter(from_width).ok_or_else(|| {
                bad(format!(
                    "the base last's fitting {from_width:?} is not a letter A-H (--from-width)"
                ))
            })?;
            k as f64 - base as f64
        } else {
            t.parse::<f64>().map_err(|_| {
                bad(format!(
                    "{t:?} is neither a fitting letter A-H nor a fitting offset (-1, 0, 1)"
                ))
            })?
        };
        if offset.abs() > 6.0 {
            return Err(bad(format!(
                "{t}: {offset} fittings from the base is too far"
            )));
        }
        if out.iter().any(|w| w.offset == offset) {
            return Err(bad(format!("fitting {t} given twice")));
        }
        out.push(Width {
            label: t.to_ascii_uppercase(),
            offset,
        });
    }
    out.sort_by(|a, b| a.offset.total_cmp(&b.offset));
    Ok(out)
}

#[derive(Clone, Debug)]
pub struct GradeSpec {
    pub system: System,
    pub mode: Mode,
    pub from: f64,
    pub sizes: Vec<f64>,
    /// Empty: the base last's fitting only.
    pub widths: Vec<Width>,
}

/// One graded last.
#[derive(Clone, Debug, Serialize)]
pub struct GradedLast {
    pub size: f64,
    pub width: Option<String>,
    /// Base file name of its STL and STEP (without extension).
    pub name: String,
    pub target_stick_length: f64,
    pub target_joint_girth: f64,
    /// Scale along the last (x) and across it (y, z).
    pub scale_length: f64,
    pub scale_girth: f64,
    pub iterations: usize,
    /// Measured on the graded mesh.
    pub measures: LastMeasures,
    #[serde(skip)]
    pub mesh: TriMesh,
}

/// One step of the table: between two neighbouring sizes of a fitting, or two neighbouring
/// fittings of a size.
#[derive(Clone, Debug, Serialize)]
pub struct Step {
    pub from: String,
    pub to: String,
    pub length_rule: f64,
    pub length_achieved: f64,
    pub girth_rule: f64,
    pub girth_achieved: f64,
    /// Other measures' steps as achieved (informative).
    pub others: Vec<(String, f64)>,
    pub ok: bool,
}

#[derive(Clone, Debug, Serialize)]
pub struct Graded {
    pub source: String,
    pub system: System,
    pub mode: Mode,
    pub from: f64,
    pub base: LastMeasures,
    /// The base last's stick length against the --from size's last length.
    pub expected_length: f64,
    pub length_per_size: f64,
    pub girth_per_size: f64,
    pub girth_per_fitting: f64,
    pub lasts: Vec<GradedLast>,
    pub steps: Vec<Step>,
    pub worst_length_error: f64,
    pub worst_girth_error: f64,
    pub notes: Vec<String>,
}

/// The bottom's height along the last in the measuring frame, smooth: the lowest vertex of
/// every 2 mm station from the heel point to 0.92 of the stick length, averaged over 10 mm
/// either way, linear between stations and constant beyond the ends (the back of the heel
/// and the toe's round front are not bottom: their lowest points would bend the heel curve
/// and move the heel point).
struct Bottom {
    x0: f64,
    dx: f64,
    z: Vec<f64>,
}

impl Bottom {
    fn of(m: &TriMesh, stick: f64) -> Bottom {
        let dx = 2.0;
        let (x0, x1) = (0.0, 0.92 * stick);
        let n = ((x1 - x0) / dx).ceil() as usize + 1;
        // The lowest point of each station's section: where the triangles' edges cross it
        // (a scanned last's bottom has long triangles, few vertices).
        let mut z = vec![f64::INFINITY; n];
        for t in 0..m.triangles.len() {
            let c = m.corners(t);
            for e in 0..3 {
                let (a, b) = (c[e], c[(e + 1) % 3]);
                let (a, b) = if a.x <= b.x { (a, b) } else { (b, a) };
                let k0 = ((a.x - x0) / dx).ceil().max(0.0) as usize;
                let k1 = ((b.x - x0) / dx).floor();
                if k1 < 0.0 {
                    continue;
                }
                let k1 = (k1 as usize).min(n - 1);
                for (k, zk) in z.iter_mut().enumerate().take(k1 + 1).skip(k0) {
                    let x = x0 + k as f64 * dx;
                    let f = if b.x > a.x {
                        (x - a.x) / (b.x - a.x)
                    } else {
                        0.0
                    };
                    *zk = zk.min(a.z + f * (b.z - a.z));
                }
            }
        }
        // Empty stations take their neighbours' heights.
        let known: Vec<usize> = (0..n).filter(|&k| z[k].is_finite()).collect();
        let raw: Vec<f64> = (0..n)
            .map(|k| {
                if z[k].is_finite() {
                    return z[k];
                }
                let b = known.iter().copied().find(|&j| j > k);
                let a = known.iter().copied().rev().find(|&j| j < k);
                match (a, b) {
                    (Some(a), Some(b)) => {
                        let t = (k - a) as f64 / (b - a) as f64;
                        z[a] + t * (z[b] - z[a])
                    }
                    (Some(a), None) => z[a],
                    (None, Some(b)) => z[b],
                    (None, None) => 0.0,
                }
            })
            .collect();
        let w = 5usize;
        let z = (0..n)
            .map(|k| {
                let (a, b) = (k.saturating_sub(w), (k + w).min(n - 1));
                raw[a..=b].iter().sum::<f64>() / (b - a + 1) as f64
            })
            .collect();
        Bottom { x0, dx, z }
    }
    fn at(&self, x: f64) -> f64 {
        if self.z.len() < 2 {
            return self.z.first().copied().unwrap_or(0.0);
        }
        let t = ((x - self.x0) / self.dx).clamp(0.0, (self.z.len() - 1) as f64);
        let k = (t.floor() as usize).min(self.z.len() - 2);
        let f = t - k as f64;
        self.z[k] + f * (self.z[k + 1] - self.z[k])
    }
}

/// The base last scaled about its heel point: x by `sx`, y and z by `syz`, the bottom's
/// heights kept at the same fraction of the length (heel height, toe spring unchanged).
fn scaled(base: &TriMesh, bottom: &Bottom, sx: f64, syz: f64) -> TriMesh {
    let mut m = base.clone();
    for p in &mut m.vertices {
        let b = bottom.at(p.x);
        *p = P3::new(sx * p.x, syz * p.y, syz * p.z + (1.0 - syz) * b);
    }
    m
}

fn label(size: f64, width: Option<&str>) -> String {
    let s = if size.fract() == 0.0 {
        format!("{size:.0}")
    } else {
        format!("{size}")
    };
    match width {
        Some(w) => format!("{s}{w}"),
        None => s,
    }
}

/// Grades `last` (a closed mesh in mm, any placement) by `spec`. Refuses a run that does not
/// hold the --from size, and a last whose stick length is further than a size group from the
/// --from size's last length, before any work.
pub fn grade(last: TriMesh, source: &str, spec: &GradeSpec) -> Result<Graded, GradeError> {
    let sys = spec.system;
    if !spec.sizes.iter().any(|&s| (s - spec.from).abs() < 1e-9) {
        return Err(GradeError::Input(format!(
            "--from {} is not in the run {} (the last as given must be one of the sizes)",
            spec.from,
            spec.sizes
                .iter()
                .map(|&s| label(s, None))
                .collect::<Vec<_>>()
                .join(", ")
        )));
    }
    let base = measure_last(last.clone(), source)?;
    let expected = sys.last_length(spec.from);
    let rel = (base.stick_length - expected) / expected;
    if rel.abs() > SIZE_GROUP {
        return Err(GradeError::Input(format!(
            "last {source}: stick length {:.1} mm does not match {} size {}: expected {:.1} mm \
             within a size group ({:.0} %, {:.1}-{:.1} mm), found {:+.1} %",
            base.stick_length,
            sys.name(),
            label(spec.from, None),
            expected,
            100.0 * SIZE_GROUP,
            expected * (1.0 - SIZE_GROUP),
            expected * (1.0 + SIZE_GROUP),
            100.0 * rel
        )));
    }
    let mut notes = Vec::new();
    if rel.abs() > 0.5 * sys.length_per_unit() / expected {
        notes.push(format!(
            "the last's stick length {:.2} mm is {:.1} {} sizes from size {}'s {:.2} mm \
             (within a size group: graded as given, its steps from its own length)",
            base.stick_length,
            (base.stick_length - expected) / sys.length_per_unit(),
            sys.name(),
            label(spec.from, None),
            expected
        ));
    }
    // The base in its measuring frame: heel point at the origin, ground z = 0, x to the toe.
    let mut m0 = last;
    let f = base.frame;
    for p in &mut m0.vertices {
        let q = *p;
        *p = P3::new(
            f[0][0] * q.x + f[0][1] * q.y + f[0][2] * q.z + f[0][3],
            f[1][0] * q.x + f[1][1] * q.y + f[1][2] * q.z + f[1][3],
            f[2][0] * q.x + f[2][1] * q.y + f[2][2] * q.z + f[2][3],
        );
    }
    let bottom = Bottom::of(&m0, base.stick_length);
    let (l0, g0) = (base.stick_length, base.joint_girth);
    let gu = sys.girth_per_unit(&base);
    let gw = sys.girth_per_fitting(&base);
    let widths: Vec<Option<&Width>> = if spec.widths.is_empty() {
        vec![None]
    } else {
        spec.widths.iter().map(Some).collect()
    };
    let mut jobs = Vec::new();
    for w in &widths {
        for &s in &spec.sizes {
            let lt = l0 + (s - spec.from) * sys.length_per_unit();
            let off = w.map_or(0.0, |w| w.offset);
            let gt = match spec.mode {
                Mode::Arithmetic => g0 + (s - spec.from) * gu,
                Mode::Geometric => g0 * lt / l0,
            } + off * gw;
            jobs.push((s, w.map(|w| w.label.clone()), lt, gt));
        }
    }
    let one = |(s, w, lt, gt): &(f64, Option<String>, f64, f64)| -> Result<GradedLast, GradeError> {
        let name = format!("{}: size {}", source, label(*s, w.as_deref()));
        let (mut sx, mut syz) = match spec.mode {
            Mode::Arithmetic => (lt / l0, gt / g0),
            Mode::Geometric => (lt / l0, lt / l0),
        };
        // Fixed-point steps on the two scales, each move limited to 3 %: the measures are
        // piecewise smooth (the joint points and the standing jump between stations), so the
        // best iterate is kept, not the last.
        let mut best: Option<(f64, GradedLast)> = None;
        for it in 1..=8 {
            let mesh = scaled(&m0, &bottom, sx, syz);
            let lm = measure_last(mesh.clone(), &name)?;
            let el = lt - lm.stick_length;
            let eg = gt - lm.joint_girth;
            let (err, done) = match spec.mode {
                Mode::Arithmetic => (
                    (el / LENGTH_TOL_MM).abs().max((eg / GIRTH_TOL_MM).abs()),
                    el.abs() < 0.02 && eg.abs() < 0.05,
                ),
                Mode::Geometric => ((el / LENGTH_TOL_MM).abs(), el.abs() < 0.02),
            };
            let (l_ratio, g_ratio) = (lt / lm.stick_length, gt / lm.joint_girth);
            if best.as_ref().is_none_or(|b| err < b.0) {
                best = Some((
                    err,
                    GradedLast {
                        size: *s,
                        width: w.clone(),
                        name: format!("size_{}", label(*s, w.as_deref())),
                        target_stick_length: *lt,
                        target_joint_girth: *gt,
                        scale_length: sx,
                        scale_girth: syz,
                        iterations: it,
                        measures: lm,
                        mesh,
                    },
                ));
            }
            if done {
                break;
            }
            sx *= l_ratio.clamp(0.97, 1.03);
            syz = match spec.mode {
                Mode::Arithmetic => syz * g_ratio.clamp(0.97, 1.03),
                Mode::Geometric => sx,
            };
        }
        Ok(best.expect("one iteration at least").1)
    };
    let threads = std::thread::available_parallelism()
        .map(|n| n.get())
        .unwrap_or(1)
        .clamp(1, 4);
    let mut results: Vec<Option<Result<GradedLast, GradeError>>> =
        (0..jobs.len()).map(|_| None).collect();
    std::thread::scope(|sc| {
        let chunks: Vec<_> = results
            .chunks_mut(jobs.len().div_ceil(threads).max(1))
            .zip(jobs.chunks(jobs.len().div_ceil(threads).max(1)))
            .collect();
        for (out, js) in chunks {
            let one = &one;
            sc.spawn(move || {
                for (o, j) in out.iter_mut().zip(js) {
                    *o = Some(one(j));
                }
            });
        }
    });
    let mut lasts = Vec::new();
    for r in results {
        lasts.push(r.expect("every job ran")?);
    }
    let steps = table_steps(&lasts);
    let worst_length_error = steps
        .iter()
        .map(|s| (s.length_achieved - s.length_rule).abs())
        .fold(0.0, f64::max);
    let worst_girth_error = steps
        .iter()
        .map(|s| (s.girth_achieved - s.girth_rule).abs())
        .fold(0.0, f64::max);
    Ok(Graded {
        source: source.to_string(),
        system: sys,
        mode: spec.mode,
        from: spec.from,
        base,
        expected_length: expected,
        length_per_size: sys.length_per_unit() * sys.size_step(),
        girth_per_size: match spec.mode {
            Mode::Arithmetic => gu * sys.size_step(),
            Mode::Geometric => g0 * sys.length_per_unit() * sys.size_step() / l0,
        },
        girth_per_fitting: gw,
        lasts,
        steps,
        worst_length_error,
        worst_girth_error,
        notes,
    })
}

fn step(a: &GradedLast, b: &GradedLast) -> Step {
    let (ma, mb) = (&a.measures, &b.measures);
    let length_rule = b.target_stick_length - a.target_stick_length;
    let girth_rule = b.target_joint_girth - a.target_joint_girth;
    let length_achieved = mb.stick_length - ma.stick_length;
    let girth_achieved = mb.joint_girth - ma.joint_girth;
    let others = ma
        .rows()
        .into_iter()
        .zip(mb.rows())
        .filter(|((n, _), _)| *n != "stick length" && *n != "joint girth")
        .map(|((n, x), (_, y))| (n.to_string(), y - x))
        .collect();
    Step {
        from: label(a.size, a.width.as_deref()),
        to: label(b.size, b.width.as_deref()),
        length_rule,
        length_achieved,
        girth_rule,
        girth_achieved,
        others,
        ok: (length_achieved - length_rule).abs() <= LENGTH_TOL_MM
            && (girth_achieved - girth_rule).abs() <= GIRTH_TOL_MM,
    }
}

/// Size steps within each fitting, then fitting steps within each size.
fn table_steps(lasts: &[GradedLast]) -> Vec<Step> {
    let mut out = Vec::new();
    let mut widths: Vec<Option<String>> = Vec::new();
    for l in lasts {
        if !widths.contains(&l.width) {
            widths.push(l.width.clone());
        }
    }
    for w in &widths {
        let run: Vec<&GradedLast> = lasts.iter().filter(|l| &l.width == w).collect();
        for p in run.windows(2) {
            out.push(step(p[0], p[1]));
        }
    }
    if widths.len() > 1 {
        let mut sizes: Vec<f64> = lasts.iter().map(|l| l.size).collect();
        sizes.sort_by(f64::total_cmp);
        sizes.dedup();
        for s in sizes {
            let row: Vec<&GradedLast> = lasts.iter().filter(|l| l.size == s).collect();
            for p in row.windows(2) {
                out.push(step(p[0], p[1]));
            }
        }
    }
    out
}

impl Graded {
    /// The measures table as CSV: one row per graded last.
    pub fn csv(&self) -> String {
        let mut s = String::from("size,width,target_stick_length,target_joint_girth");
        for (n, _) in self.base.rows() {
            s.push(',');
            s.push_str(&n.replace(' ', "_"));
        }
        s.push_str(",scale_length,scale_girth\n");
        for l in &self.lasts {
            s.push_str(&format!(
                "{},{},{:.3},{:.3}",
                label(l.size, None),
                l.width.clone().unwrap_or_default(),
                l.target_stick_length,
                l.target_joint_girth
            ));
            for (_, v) in l.measures.rows() {
                s.push_str(&format!(",{v:.3}"));
            }
            s.push_str(&format!(",{:.5},{:.5}\n", l.scale_length, l.scale_girth));
        }
        s
    }

    /// The steps table as CSV.
    pub fn steps_csv(&self) -> String {
        let mut s =
            String::from("from,to,length_rule,length_achieved,girth_rule,girth_achieved,ok");
        if let Some(st) = self.steps.first() {
            for (n, _) in &st.others {
                s.push_str(&format!(",{}", n.replace(' ', "_")));
            }
        }
        s.push('\n');
        for st in &self.steps {
            s.push_str(&format!(
                "{},{},{:.3},{:.3},{:.3},{:.3},{}",
                st.from,
                st.to,
                st.length_rule,
                st.length_achieved,
                st.girth_rule,
                st.girth_achieved,
                st.ok
            ));
            for (_, v) in &st.others {
                s.push_str(&format!(",{v:.3}"));
            }
            s.push('\n');
        }
        s
    }

    /// The printed table: the measures of every size, then the steps against the rule.
    pub fn table(&self) -> String {
        let mut s = format!(
            "{} graded {} from size {} ({} mode): {:.3} mm length and {:.3} mm joint girth a size{}\n",
            self.source,
            self.system.name(),
            label(self.from, None),
            match self.mode {
                Mode::Arithmetic => "arithmetic",
                Mode::Geometric => "geometric",
            },
            self.length_per_size,
            self.girth_per_size,
            if self.lasts.iter().any(|l| l.width.is_some()) {
                format!(", {:.3} mm girth a fitting", self.girth_per_fitting)
            } else {
                String::new()
            }
        );
        for n in &self.notes {
            s.push_str(&format!("note: {n}\n"));
        }
        s.push_str("  size  stick  bottom  heel h.  toe sp.  joint w.  joint g.  waist g.  instep g.  l.heel g.  it\n");
        for l in &self.lasts {
            let m = &l.measures;
            s.push_str(&format!(
                "  {:5} {:6.2} {:7.2} {:8.2} {:8.2} {:9.2} {:9.2} {:9.2} {:10.2} {:10.2} {:3}\n",
                label(l.size, l.width.as_deref()),
                m.stick_length,
                m.bottom_length,
                m.heel_height,
                m.toe_spring,
                m.joint_width,
                m.joint_girth,
                m.waist_girth,
                m.instep_girth,
                m.long_heel_girth,
                l.iterations
            ));
        }
        s.push_str(
            "  step        length: rule  achieved   girth: rule  achieved   instep g.  joint w.\n",
        );
        for st in &self.steps {
            let other = |n: &str| {
                st.others
                    .iter()
                    .find(|o| o.0 == n)
                    .map_or(f64::NAN, |o| o.1)
            };
            s.push_str(&format!(
                "  {:>4} -> {:4} {:12.3} {:9.3} {:13.3} {:9.3} {:11.3} {:9.3}  {}\n",
                st.from,
                st.to,
                st.length_rule,
                st.length_achieved,
                st.girth_rule,
                st.girth_achieved,
                other("instep girth"),
                other("joint width"),
                if st.ok { "ok" } else { "OUT" }
            ));
        }
        s.push_str(&format!(
            "worst step error: length {:.3} mm (bound {LENGTH_TOL_MM}), joint girth {:.3} mm (bound {GIRTH_TOL_MM})\n",
            self.worst_length_error, self.worst_girth_error
        ));
        s
    }
}

/// A closed mesh as a STEP FACETED_BREP (one planar face per triangle), millimetres.
pub fn mesh_step(m: &TriMesh, name: &str) -> String {
    let mut w = Document::new(
        &Header::new(name),
        "footscan graded last: faceted closed solid, millimetres",
    );
    let (nm, ctx, pds, axis) = (w.name.clone(), w.ctx, w.pds, w.axis);
    let pts: Vec<usize> = m.vertices.iter().map(|&p| w.point(p)).collect();
    let mut faces = Vec::with_capacity(m.triangles.len());
    for (t, tri) in m.triangles.iter().enumerate() {
        let [a, b, _] = m.corners(t);
        let n = m.face_normal(t);
        let e = b - a;
        let e = e - n * e.dot(&n);
        let e = if e.norm() > 0.0 { e / e.norm() } else { e };
        let lp = w.add(format!(
            "POLY_LOOP('',(#{},#{},#{}))",
            pts[tri[0] as usize], pts[tri[1] as usize], pts[tri[2] as usize]
        ));
        let bound = w.add(format!("FACE_OUTER_BOUND('',#{lp},.T.)"));
        let nd = w.add(format!(
            "DIRECTION('',({},{},{}))",
            real(n.x),
            real(n.y),
            real(n.z)
        ));
        let xd = w.add(format!(
            "DIRECTION('',({},{},{}))",
            real(e.x),
            real(e.y),
            real(e.z)
        ));
        let ax = w.add(format!(
            "AXIS2_PLACEMENT_3D('',#{},#{nd},#{xd})",
            pts[tri[0] as usize]
        ));
        let pl = w.add(format!("PLANE('',#{ax})"));
        faces.push(w.add(format!("FACE_SURFACE('',(#{bound}),#{pl},.T.)")));
    }
    let shell = w.add(format!(
        "CLOSED_SHELL('',({}))",
        faces
            .iter()
            .map(|f| format!("#{f}"))
            .collect::<Vec<_>>()
            .join(",")
    ));
    let brep = w.add(format!("FACETED_BREP({nm},#{shell})"));
    let rep = w.add(format!(
        "FACETED_BREP_SHAPE_REPRESENTATION({nm},(#{brep},#{axis}),#{ctx})"
    ));
    w.add(format!("SHAPE_DEFINITION_REPRESENTATION(#{pds},#{rep})"));
    w.finish()
}

/// The file names [`write_graded_atomic`] writes besides each last's STL and STEP.
pub const TABLE_FILES: [&str; 3] = ["grade.csv", "steps.csv", "grade.json"];

/// Writes every graded last (`size_40.stl`, `size_40.step`, ...; the measuring frame of the
/// base last: heel point at the origin, ground z = 0, x to the toe, mm) and the tables into a
/// temporary directory beside `out`, which then replaces `out` as a whole. Returns the files.
pub fn write_graded_atomic(g: &Graded, out: &Path) -> Result<Vec<PathBuf>, GradeError> {
    let err = |p: &Path, why: String| GradeError::Output {
        path: p.display().to_string(),
        why,
    };
    let write = |dir: &Path| -> Result<Vec<PathBuf>, GradeError> {
        std::fs::create_dir_all(dir).map_err(|e| err(dir, e.to_string()))?;
        let mut files = Vec::new();
        for l in &g.lasts {
            let p = dir.join(format!("{}.stl", l.name));
            l.mesh
                .write(&p, Format::StlBinary)
                .map_err(|e| err(&p, e.to_string()))?;
            files.push(out.join(format!("{}.stl", l.name)));
            let p = dir.join(format!("{}.step", l.name));
            std::fs::write(&p, mesh_step(&l.mesh, &l.name)).map_err(|e| err(&p, e.to_string()))?;
            files.push(out.join(format!("{}.step", l.name)));
        }
        let json = serde_json::to_string_pretty(g).map_err(|e| err(dir, e.to_string()))?;
        for (f, text) in TABLE_FILES.iter().zip([g.csv(), g.steps_csv(), json]) {
            let p = dir.join(f);
            std::fs::write(&p, text).map_err(|e| err(&p, e.to_string()))?;
            files.push(out.join(f));
        }
        Ok(files)
    };
    crate::outdir::write_dir_atomic(out, |tmp| {
        write(tmp).map_err(|e| match e {
            GradeError::Output { path, why } => (path.into(), why),
            e => (tmp.to_path_buf(), e.to_string()),
        })
    })
    .map_err(|(p, why)| err(&p, why))
}
