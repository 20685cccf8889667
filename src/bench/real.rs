//! Detectors on real frames made by other scanners (`footscan bench real --data DIR`).
//!
//! There is no ground truth, but a laser line on a flat board is straight, and a static part
//! of the scene gives the same line frame after frame. `DIR/MANIFEST.csv` lists per frame: the
//! laser's colour, whether the line is stored one column per row (V) or one row per column (H,
//! transposed here), the channel that separates it, the flat-board regions of interest
//! (`x0:y0:x1:y1;...` in the stored image), groups of regions that are static across frames,
//! and the laser-off partner. Per frame, region and detector:
//! - `visible`: rows of the region whose channel peak stands out of the row's median by at least
//!   a third of the region's typical (90th percentile) contrast and 12 DN: the line is there;
//! - `found`: visible rows with an accepted line; `found_pct` = found / visible; `missed`: the
//!   visible rows without one, by the coarse search's reason (threshold, ambiguous, saturated,
//!   border; `subpixel` when the row passed the search but the estimator gave no column);
//! - `resid_px`: RMS of the residuals to a robust polynomial in the row (order 3, refitted
//!   with Tukey biweights), over the rows within 2 px of it; `outliers`: found rows beyond 2 px;
//! - laser-off frames: the rows of the whole frame with a line (false detections);
//! - static groups: per row present in every frame of the group, the spread (standard
//!   deviation) of the column across frames, RMS over those rows.

use footscan::detect::{build_with_prep, files, DetectParams, Detector, Image, LinePeak, NAMES};
use footscan_hal::Pixels;
use serde::Serialize;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// One frame x region x detector.
#[derive(Clone, Debug, Serialize)]
pub struct RealRow {
    pub frame: String,
    /// `x0:y0:x1:y1` as in the manifest, or `off` for a laser-off frame (whole frame).
    pub region: String,
    pub channel: String,
    /// Laser-off partner subtracted.
    pub background: bool,
    pub detector: String,
    pub rows: usize,
    pub visible: usize,
    pub found: usize,
    pub found_pct: f64,
    /// Visible rows without a line, by reason (`ambiguous 40, below_threshold 3`).
    pub missed: String,
    pub resid_px: f64,
    pub outliers: usize,
}

/// Frame-to-frame spread of one static group.
#[derive(Clone, Debug, Serialize)]
pub struct SpreadRow {
    pub group: String,
    pub frames: usize,
    pub detector: String,
    pub rows: usize,
    pub spread_px: f64,
}

/// The frames directory: `FOOTSCAN_DATA/frames`, else `<repo>/../shared/data/frames`.
pub fn default_data_dir() -> PathBuf {
    match std::env::var_os("FOOTSCAN_DATA") {
        Some(d) => PathBuf::from(d).join("frames"),
        None => Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/data/frames"),
    }
}

/// One line of MANIFEST.csv (the columns used here).
#[derive(Clone, Debug)]
pub struct Entry {
    pub path: String,
    pub source: String,
    pub laser: String,
    /// Line stored one row per column: transpose.
    pub transpose: bool,
    pub channel: String,
    pub rois: Vec<[u32; 4]>,
    pub groups: Vec<(String, [u32; 4])>,
    pub partner: String,
}

/// Split one CSV line (double quotes, "" inside quotes).
fn csv_fields(line: &str) -> Vec<String> {
    let mut out = vec![String::new()];
    let mut quoted = false;
    let mut it = line.chars().peekable();
    while let Some(c) = it.next() {
        match (c, quoted) {
            ('"', true) if it.peek() == Some(&'"') => {
                it.next();
                out.last_mut().unwrap().push('"');
            }
            ('"', _) => quoted = !quoted,
            (',', false) => out.push(String::new()),
            (c, _) => out.last_mut().unwrap().push(c),
        }
    }
    out
}

fn rect(s: &str) -> Result<[u32; 4], String> {
    let v: Vec<u32> = s
        .split(':')
        .map(|x| x.trim().parse::<u32>())
        .collect::<Result<_, _>>()
        .map_err(|e| format!("region {s:?}: {e}"))?;
    v.try_into()
        .map_err(|_| format!("region {s:?}: want x0:y0:x1:y1"))
}

/// Read `dir/MANIFEST.csv`.
pub fn manifest(dir: &Path) -> Result<Vec<Entry>, String> {
    let p = dir.join("MANIFEST.csv");
    let text = std::fs::read_to_string(&p).map_err(|e| format!("{}: {e}", p.display()))?;
    let mut out = Vec::new();
    for (i, line) in text.lines().enumerate().skip(1) {
        if line.trim().is_empty() {
            continue;
        }
        let f = csv_fields(line);
        if f.len() < 12 {
            return Err(format!(
                "{}:{}: {} fields, want 13",
                p.display(),
                i + 1,
                f.len()
            ));
        }
        let mut rois = Vec::new();
        for r in f[9].split(';').filter(|s| !s.trim().is_empty()) {
            rois.push(rect(r)?);
        }
        let mut groups = Vec::new();
        for g in f[10].split(';').filter(|s| !s.trim().is_empty()) {
            let (name, r) = g.split_once(':').ok_or(format!("group {g:?}"))?;
            groups.push((name.to_string(), rect(r)?));
        }
        out.push(Entry {
            path: f[0].clone(),
            source: f[1].clone(),
            laser: f[6].trim().to_string(),
            transpose: f[7].trim_start().starts_with('H'),
            channel: f[8].trim().to_string(),
            rois,
            groups,
            partner: f[11].trim().to_string(),
        });
    }
    Ok(out)
}

/// The partner's path: relative to the frame's folder, else to its source's folder.
fn partner_path(dir: &Path, e: &Entry) -> Option<PathBuf> {
    if e.partner.is_empty() {
        return None;
    }
    let own = dir.join(&e.path);
    [
        own.parent().map(|p| p.join(&e.partner)),
        Some(dir.join(&e.source).join(&e.partner)),
    ]
    .into_iter()
    .flatten()
    .find(|p| p.is_file())
}

/// A region of the stored image in the detection frame (transposed for H lines).
fn region(img: &Image, r: [u32; 4], transpose: bool) -> Image {
    let c = img.crop(r[0], r[1], r[2], r[3]);
    if transpose {
        c.transposed()
    } else {
        c
    }
}

fn params(channel: &str) -> Result<DetectParams, String> {
    Ok(DetectParams {
        channel: Some(footscan::detect::Channel::parse(channel).map_err(|e| e.to_string())?),
        ..Default::default()
    })
}

/// Rows where the line is visible (see the module doc), from the channel image.
fn visible_rows(f: &footscan_hal::Frame) -> Vec<bool> {
    let w = f.width as usize;
    let contrast: Vec<f32> = (0..f.height as usize)
        .map(|r| {
            let mut v: Vec<f32> = (0..w).map(|c| f.get(r, c)).collect();
            let mx = v.iter().copied().fold(0.0, f32::max);
            let mid = v.len() / 2;
            let med = *v.select_nth_unstable_by(mid, |a, b| a.total_cmp(b)).1;
            mx - med
        })
        .collect();
    let mut s = contrast.clone();
    s.sort_by(|a, b| a.total_cmp(b));
    let p90 = s[(s.len() * 9 / 10).min(s.len() - 1)];
    let scale = match f.pixels {
        Pixels::Gray8(_) => 1.0,
        Pixels::Gray16(_) => 257.0,
    };
    contrast
        .iter()
        .map(|&c| c >= (p90 / 3.0).max(12.0 * scale))
        .collect()
}

/// Least squares polynomial of `order` through (x, y) with weights w: coefficients.
fn polyfit(x: &[f64], y: &[f64], w: &[f64], order: usize) -> Option<Vec<f64>> {
    let k = order + 1;
    let mut a = vec![vec![0.0; k + 1]; k];
    for ((&xi, &yi), &wi) in x.iter().zip(y).zip(w) {
        let mut p = vec![1.0; k];
        for j in 1..k {
            p[j] = p[j - 1] * xi;
        }
        for r in 0..k {
            for c in 0..k {
                a[r][c] += wi * p[r] * p[c];
            }
            a[r][k] += wi * p[r] * yi;
        }
    }
    // Gaussian elimination with partial pivoting.
    for c in 0..k {
        let piv = (c..k).max_by(|&i, &j| a[i][c].abs().total_cmp(&a[j][c].abs()))?;
        if a[piv][c].abs() < 1e-12 {
            return None;
        }
        a.swap(c, piv);
        for r in 0..k {
            if r != c {
                let f = a[r][c] / a[c][c];
                let pivot_row = a[c].clone();
                for (x, p) in a[r].iter_mut().zip(&pivot_row).skip(c) {
                    *x -= f * p;
                }
            }
        }
    }
    Some((0..k).map(|i| a[i][k] / a[i][i]).collect())
}

/// Residuals of (row, col) to a robust cubic in the row (Tukey biweight IRLS from a
/// least-squares start), rows scaled to [-1, 1].
pub fn robust_residuals(rows: &[f64], cols: &[f64]) -> Vec<f64> {
    let n = rows.len();
    if n < 8 {
        return vec![f64::NAN; n];
    }
    let (lo, hi) = (rows[0], rows[n - 1]);
    let x: Vec<f64> = rows
        .iter()
        .map(|&r| 2.0 * (r - lo) / (hi - lo).max(1.0) - 1.0)
        .collect();
    let mut w = vec![1.0; n];
    let mut res = vec![0.0; n];
    for _ in 0..20 {
        let Some(c) = polyfit(&x, cols, &w, 3) else {
            return vec![f64::NAN; n];
        };
        for i in 0..n {
            let f = c.iter().rev().fold(0.0, |acc, &ci| acc * x[i] + ci);
            res[i] = cols[i] - f;
        }
        let mut a: Vec<f64> = res.iter().map(|r| r.abs()).collect();
        let mid = n / 2;
        let mad = *a.select_nth_unstable_by(mid, |p, q| p.total_cmp(q)).1;
        let s = (4.685 * 1.4826 * mad).max(0.05);
        for i in 0..n {
            let u = res[i] / s;
            w[i] = if u.abs() < 1.0 {
                (1.0 - u * u).powi(2)
            } else {
                0.0
            };
        }
    }
    res
}

fn detect_all(det: &mut dyn Detector, f: &footscan_hal::Frame) -> Vec<LinePeak> {
    let mut out = vec![LinePeak::NONE; f.height as usize];
    det.detect(f, &mut out);
    out
}

/// The whole benchmark: the region table, the static-group spreads.
pub fn run(dir: &Path, detectors: &[String]) -> Result<(Vec<RealRow>, Vec<SpreadRow>), String> {
    let entries = manifest(dir)?;
    let mut rows = Vec::new();
    // group -> detector -> per frame: column per row of the group's region.
    let mut groups: BTreeMap<String, BTreeMap<String, Vec<Vec<f64>>>> = BTreeMap::new();
    let load = |p: &Path| files::load_image(p, 0).map_err(|e| e.to_string());
    for e in &entries {
        if e.laser == "none" || e.channel.is_empty() {
            continue;
        }
        let path = dir.join(&e.path);
        let img = load(&path)?;
        let partner = partner_path(dir, e)
            .map(|p| load(&p).map(|i| (p, i)))
            .transpose()?;
        // Laser-off partner: no line anywhere (its own row, whole frame, the on frame's channel).
        if let Some((pp, off)) = &partner {
            let off_t = if e.transpose {
                off.transposed()
            } else {
                off.clone_image()
            };
            for d in detectors {
                let (mut det, mut prep) =
                    build_with_prep(d, &params(&e.channel)?).map_err(|e| e.to_string())?;
                let f = prep
                    .prepare(&off_t, &pp.display().to_string())
                    .map_err(|e| e.to_string())?;
                let out = detect_all(det.as_mut(), f);
                let found = out.iter().filter(|p| p.is_valid()).count();
                rows.push(RealRow {
                    frame: pp.strip_prefix(dir).unwrap_or(pp).display().to_string(),
                    region: "off".into(),
                    channel: e.channel.clone(),
                    background: false,
                    detector: d.clone(),
                    rows: out.len(),
                    visible: 0,
                    found,
                    found_pct: f64::NAN,
                    missed: String::new(),
                    resid_px: f64::NAN,
                    outliers: found,
                });
            }
        }
        let mut regions: Vec<(String, [u32; 4], Option<String>)> = e
            .rois
            .iter()
            .map(|r| (format!("{}:{}:{}:{}", r[0], r[1], r[2], r[3]), *r, None))
            .collect();
        for (g, r) in &e.groups {
            regions.push((g.to_string(), *r, Some(g.clone())));
        }
        for (name, r, group) in regions {
            let sub = region(&img, r, e.transpose);
            if sub.size().0 < 8 || sub.size().1 < 8 {
                return Err(format!(
                    "{}: region {name} lies outside the {} image",
                    e.path,
                    img.describe()
                ));
            }
            let sub_off = partner.as_ref().map(|(_, off)| region(off, r, e.transpose));
            for use_bg in [false, true] {
                if use_bg && sub_off.is_none() {
                    continue;
                }
                for d in detectors {
                    let (mut det, mut prep) =
                        build_with_prep(d, &params(&e.channel)?).map_err(|e| e.to_string())?;
                    if use_bg {
                        prep.set_background(sub_off.as_ref().unwrap(), "partner")
                            .map_err(|e| e.to_string())?;
                    }
                    let f = prep.prepare(&sub, &e.path).map_err(|e| e.to_string())?;
                    let vis = visible_rows(f);
                    let out = detect_all(det.as_mut(), f);
                    let (mut rr, mut cc) = (Vec::new(), Vec::new());
                    let mut found = 0;
                    let mut missed: BTreeMap<&str, usize> = BTreeMap::new();
                    for (i, p) in out.iter().enumerate() {
                        if p.is_valid() {
                            rr.push(i as f64);
                            cc.push(p.col);
                            found += vis[i] as usize;
                        } else if vis[i] {
                            *missed
                                .entry(p.reject.map_or("subpixel", |r| r.as_str()))
                                .or_default() += 1;
                        }
                    }
                    let missed = missed
                        .iter()
                        .map(|(k, v)| format!("{k} {v}"))
                        .collect::<Vec<_>>()
                        .join(", ");
                    let res = robust_residuals(&rr, &cc);
                    let inl: Vec<f64> = res.iter().copied().filter(|r| r.abs() <= 2.0).collect();
                    let resid =
                        (inl.iter().map(|r| r * r).sum::<f64>() / inl.len().max(1) as f64).sqrt();
                    let visible = vis.iter().filter(|&&v| v).count();
                    if let (Some(g), false) = (&group, use_bg) {
                        let col: Vec<f64> = out
                            .iter()
                            .map(|p| if p.is_valid() { p.col } else { f64::NAN })
                            .collect();
                        groups
                            .entry(g.clone())
                            .or_default()
                            .entry(d.clone())
                            .or_default()
                            .push(col);
                    }
                    // Static groups are not flat: they give the spread, not a straightness.
                    if group.is_some() {
                        continue;
                    }
                    rows.push(RealRow {
                        frame: e.path.clone(),
                        region: name.clone(),
                        channel: e.channel.clone(),
                        background: use_bg,
                        detector: d.clone(),
                        rows: out.len(),
                        visible,
                        found,
                        found_pct: 100.0 * found as f64 / visible.max(1) as f64,
                        missed,
                        resid_px: if inl.len() >= 8 { resid } else { f64::NAN },
                        outliers: res.len() - inl.len(),
                    });
                }
            }
        }
    }
    let mut spreads = Vec::new();
    for (g, by_det) in groups {
        for d in detectors {
            let Some(frames) = by_det.get(d) else {
                continue;
            };
            let n = frames.len();
            let h = frames.iter().map(|f| f.len()).min().unwrap_or(0);
            let (mut s2, mut k) = (0.0, 0usize);
            for r in 0..h {
                let v: Vec<f64> = frames.iter().map(|f| f[r]).collect();
                if n < 2 || v.iter().any(|x| !x.is_finite()) {
                    continue;
                }
                let m = v.iter().sum::<f64>() / n as f64;
                let var = v.iter().map(|x| (x - m) * (x - m)).sum::<f64>() / (n - 1) as f64;
                // A row where the frames disagree by more than 2 px is a different surface.
                if var.sqrt() > 2.0 {
                    continue;
                }
                s2 += var;
                k += 1;
            }
            spreads.push(SpreadRow {
                group: g.clone(),
                frames: n,
                detector: d.clone(),
                rows: k,
                spread_px: (s2 / k.max(1) as f64).sqrt(),
            });
        }
    }
    Ok((rows, spreads))
}

/// The baselines a detector's straightness is compared with (issue 34's targets).
pub const BASELINES: [&str; 5] = ["cog", "steger", "gaussian", "blais-rioux", "parabolic"];
/// A region counts as found when at least this share of its visible rows has a line (%).
pub const FOUND_PCT: f64 = 98.0;
/// A detector is as straight as the best baseline when its residual is within this factor.
pub const STRAIGHT_FACTOR: f64 = 1.05;

/// Per folder of the frames directory and detector: the two shares of issue 34's targets.
#[derive(Clone, Debug, Serialize)]
pub struct ShareRow {
    /// First component of the frame's path (one scanner project), or `all`.
    pub folder: String,
    pub detector: String,
    /// Flat-board regions with visible rows (each frame x region x with/without background).
    pub regions: usize,
    /// Share of them with at least [`FOUND_PCT`] % of the visible rows found.
    pub found_share: f64,
    /// Regions where some baseline has a residual.
    pub compared: usize,
    /// Share of those where the detector's residual is within [`STRAIGHT_FACTOR`] of the
    /// straightest of [`BASELINES`] (a detector without a residual there is not).
    pub straight_share: f64,
}

/// The two shares per folder and detector (and over all folders), from the region rows.
pub fn shares(rows: &[RealRow]) -> Vec<ShareRow> {
    type Key<'a> = (&'a str, &'a str, bool);
    let folder = |r: &RealRow| r.frame.split('/').next().unwrap_or("").to_string();
    // Region -> straightest baseline residual.
    let mut best: BTreeMap<Key, f64> = BTreeMap::new();
    for r in rows.iter().filter(|r| r.region != "off" && r.visible > 0) {
        if BASELINES.contains(&r.detector.as_str()) && r.resid_px.is_finite() {
            let b = best
                .entry((&r.frame, &r.region, r.background))
                .or_insert(f64::INFINITY);
            *b = b.min(r.resid_px);
        }
    }
    let mut folders: Vec<String> = rows.iter().map(folder).collect();
    folders.sort();
    folders.dedup();
    folders.push("all".into());
    let mut dets: Vec<&str> = Vec::new();
    for r in rows {
        if !dets.contains(&r.detector.as_str()) {
            dets.push(&r.detector);
        }
    }
    let mut out = Vec::new();
    for f in &folders {
        for &d in &dets {
            let (mut n, mut found, mut cmp, mut straight) = (0usize, 0usize, 0usize, 0usize);
            for r in rows.iter().filter(|r| {
                r.detector == d
                    && r.region != "off"
                    && r.visible > 0
                    && (f == "all" || folder(r) == *f)
            }) {
                n += 1;
                found += (r.found_pct >= FOUND_PCT) as usize;
                if let Some(&b) = best.get(&(r.frame.as_str(), r.region.as_str(), r.background)) {
                    cmp += 1;
                    straight +=
                        (r.resid_px.is_finite() && r.resid_px <= STRAIGHT_FACTOR * b) as usize;
                }
            }
            if n > 0 {
                out.push(ShareRow {
                    folder: f.clone(),
                    detector: d.to_string(),
                    regions: n,
                    found_share: found as f64 / n as f64,
                    compared: cmp,
                    straight_share: if cmp > 0 {
                        straight as f64 / cmp as f64
                    } else {
                        f64::NAN
                    },
                });
            }
        }
    }
    out
}

/// The shares as text.
pub fn share_table(shares: &[ShareRow]) -> String {
    let mut s = format!(
        "\n{:<28} {:<12} {:>7} {:>9} {:>8} {:>10}\n",
        "folder", "detector", "regions", "found98%", "compared", "straight5%"
    );
    for r in shares {
        s += &format!(
            "{:<28} {:<12} {:>7} {:>9.1} {:>8} {:>10.1}\n",
            r.folder,
            r.detector,
            r.regions,
            100.0 * r.found_share,
            r.compared,
            100.0 * r.straight_share
        );
    }
    s
}

/// Every detector's name.
pub fn all_detectors() -> Vec<String> {
    NAMES.iter().map(|s| s.to_string()).collect()
}

/// Both tables as text.
pub fn table(rows: &[RealRow], spreads: &[SpreadRow]) -> String {
    let mut s = format!(
        "{:<58} {:<16} {:<10} {:>3} {:<12} {:>5} {:>5} {:>5} {:>7} {:>8} {:>5}  {}\n",
        "frame",
        "region",
        "channel",
        "bg",
        "detector",
        "rows",
        "vis",
        "found",
        "found%",
        "resid",
        "out",
        "missed"
    );
    for r in rows {
        s += &format!(
            "{:<58} {:<16} {:<10} {:>3} {:<12} {:>5} {:>5} {:>5} {:>7.1} {:>8.4} {:>5}  {}\n",
            r.frame,
            r.region,
            r.channel,
            if r.background { "yes" } else { "no" },
            r.detector,
            r.rows,
            r.visible,
            r.found,
            r.found_pct,
            r.resid_px,
            r.outliers,
            r.missed
        );
    }
    s += &format!(
        "\n{:<20} {:>6} {:<12} {:>5} {:>9}\n",
        "static group", "frames", "detector", "rows", "spread_px"
    );
    for r in spreads {
        s += &format!(
            "{:<20} {:>6} {:<12} {:>5} {:>9.4}\n",
            r.group, r.frames, r.detector, r.rows, r.spread_px
        );
    }
    s
}

#[cfg(test)]
mod share_tests {
    use super::*;

    fn row(frame: &str, det: &str, found_pct: f64, resid: f64) -> RealRow {
        RealRow {
            frame: frame.into(),
            region: "0:0:10:10".into(),
            channel: "R".into(),
            background: false,
            detector: det.into(),
            rows: 10,
            visible: 10,
            found: 0,
            found_pct,
            missed: String::new(),
            resid_px: resid,
            outliers: 0,
        }
    }

    #[test]
    fn shares_count_regions_per_folder_against_the_straightest_baseline() {
        let rows = vec![
            // a/1: bp finds all, 1.04x the best baseline (steger 0.30): straight.
            row("a/1.png", "bezier-plus", 100.0, 0.312),
            row("a/1.png", "cog", 100.0, 0.40),
            row("a/1.png", "steger", 90.0, 0.30),
            // a/2: bp finds 97.9 %, 1.1x the best: neither.
            row("a/2.png", "bezier-plus", 97.9, 0.33),
            row("a/2.png", "cog", 100.0, 0.30),
            // b/1: bp has no residual: not straight; no line found by anyone else.
            row("b/1.png", "bezier-plus", 98.0, f64::NAN),
            row("b/1.png", "cog", 0.0, 0.2),
        ];
        let sh = shares(&rows);
        let get = |f: &str, d: &str| {
            sh.iter()
                .find(|r| r.folder == f && r.detector == d)
                .unwrap()
                .clone()
        };
        let a = get("a", "bezier-plus");
        assert_eq!((a.regions, a.compared), (2, 2));
        assert_eq!((a.found_share, a.straight_share), (0.5, 0.5));
        let b = get("b", "bezier-plus");
        assert_eq!((b.found_share, b.straight_share), (1.0, 0.0));
        let all = get("all", "bezier-plus");
        assert_eq!(all.regions, 3);
        assert!((all.found_share - 2.0 / 3.0).abs() < 1e-12);
        assert!((all.straight_share - 1.0 / 3.0).abs() < 1e-12);
        // A baseline is within 5 % of itself where it is the best.
        assert_eq!(get("a", "steger").straight_share, 1.0);
    }
}
