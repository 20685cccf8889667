//! Blending functions b(t): the weight of the morph in a fill slice, against 1 - b for the
//! extension, at the slice's position t across the gap (0 at the back part's boundary slice,
//! 1 at the toe part's).
//!
//! Near the boundaries the extension should dominate (it carries the parts' tangent planes
//! and curvature into the gap), near the middle the morph (it joins the two shapes without
//! the step two extensions would leave where they meet). How fast b leaves 0 decides what
//! survives at the seam: a b that grows linearly bends the fill by a term of second order in
//! the distance from the seam (tangent kept, curvature not), one that grows quadratically
//! only by a third-order term (curvature kept too).

use std::path::Path;

/// A blending function.
#[derive(Debug, Clone, PartialEq)]
pub enum Weight {
    /// b = 1: the linear morph alone.
    Morph,
    /// b = 0: the two extensions alone, meeting in the middle.
    Extension,
    /// Piecewise linear: 0 at both boundaries, 1 in the middle.
    Linear,
    /// Polynomial: 3 s^2 - 2 s^3 of s = 2 min(t, 1 - t): 0 with zero slope at the
    /// boundaries, 1 with zero slope in the middle.
    Poly,
    /// A table of (t, b) pairs, linear between them and constant beyond the ends.
    Table(Vec<(f64, f64)>),
}

/// Why a blend table was refused; names the file and the line.
#[derive(Debug, thiserror::Error)]
pub enum TableError {
    #[error("blend table {path}")]
    Io {
        path: String,
        source: std::io::Error,
    },
    #[error(
        "blend table {path}, line {line}: {reason}; expected two numbers per line, \
         t in [0, 1] increasing and b in [0, 1] ('#' starts a comment)"
    )]
    Line {
        path: String,
        line: usize,
        reason: String,
    },
    #[error("blend table {path}: {n} rows; need at least 2")]
    TooShort { path: String, n: usize },
}

impl Weight {
    /// The morph's weight at position `t` across the gap.
    pub fn at(&self, t: f64) -> f64 {
        let t = t.clamp(0.0, 1.0);
        let s = 2.0 * t.min(1.0 - t);
        match self {
            Weight::Morph => 1.0,
            Weight::Extension => 0.0,
            Weight::Linear => s,
            Weight::Poly => crate::smoothstep(s),
            Weight::Table(rows) => table_at(rows, t),
        }
    }

    /// A short name for tables and file names.
    pub fn name(&self) -> String {
        match self {
            Weight::Morph => "morph".into(),
            Weight::Extension => "extension".into(),
            Weight::Linear => "linear".into(),
            Weight::Poly => "poly".into(),
            Weight::Table(_) => "table".into(),
        }
    }

    /// Read a table: lines of `t b`, whitespace or comma separated.
    pub fn read_table(path: &Path) -> Result<Weight, TableError> {
        let p = path.display().to_string();
        let text = std::fs::read_to_string(path).map_err(|source| TableError::Io {
            path: p.clone(),
            source,
        })?;
        Weight::parse_table(&text, &p)
    }

    /// Parse table text; `path` names it in errors.
    pub fn parse_table(text: &str, path: &str) -> Result<Weight, TableError> {
        let mut rows: Vec<(f64, f64)> = Vec::new();
        for (k, raw) in text.lines().enumerate() {
            let line = raw.split('#').next().unwrap_or("").trim();
            if line.is_empty() {
                continue;
            }
            let bad = |reason: String| TableError::Line {
                path: path.to_string(),
                line: k + 1,
                reason,
            };
            let nums: Vec<&str> = line
                .split(|c: char| c.is_whitespace() || c == ',')
                .filter(|s| !s.is_empty())
                .collect();
            if nums.len() != 2 {
                return Err(bad(format!("{} fields in {line:?}", nums.len())));
            }
            let parse = |s: &str| {
                s.parse::<f64>()
                    .map_err(|_| bad(format!("{s:?} is not a number")))
            };
            let (t, b) = (parse(nums[0])?, parse(nums[1])?);
            if !(0.0..=1.0).contains(&t) || !(0.0..=1.0).contains(&b) {
                return Err(bad(format!("({t}, {b}) outside [0, 1]")));
            }
            if rows.last().is_some_and(|r| t <= r.0) {
                return Err(bad(format!("t = {t} does not increase")));
            }
            rows.push((t, b));
        }
        if rows.len() < 2 {
            return Err(TableError::TooShort {
                path: path.to_string(),
                n: rows.len(),
            });
        }
        Ok(Weight::Table(rows))
    }
}

/// Piecewise linear interpolation in a table sorted by t.
pub fn table_at(rows: &[(f64, f64)], t: f64) -> f64 {
    match rows.iter().position(|r| r.0 >= t) {
        None => rows.last().map_or(0.0, |r| r.1),
        Some(0) => rows[0].1,
        Some(i) => {
            let (a, b) = (rows[i - 1], rows[i]);
            a.1 + (b.1 - a.1) * (t - a.0) / (b.0 - a.0)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn err(text: &str) -> String {
        Weight::parse_table(text, "b.txt").unwrap_err().to_string()
    }

    #[test]
    fn table_rows_with_comments_commas_and_blank_lines() {
        let w = Weight::parse_table("# t b\n0 0\n\n0.5, 1  # middle\n1\t0.2\n", "b.txt").unwrap();
        assert_eq!(w, Weight::Table(vec![(0.0, 0.0), (0.5, 1.0), (1.0, 0.2)]));
        assert!((w.at(0.25) - 0.5).abs() < 1e-12);
        assert!((w.at(0.75) - 0.6).abs() < 1e-12);
        // Constant beyond the ends of a table that does not span [0, 1].
        let w = Weight::parse_table("0.2 0.4\n0.8 0.6", "b.txt").unwrap();
        assert_eq!((w.at(0.0), w.at(1.0)), (0.4, 0.6));
    }

    #[test]
    fn bad_tables_name_the_file_and_the_line() {
        let e = err("0 0\n0.5 1 2\n");
        assert!(e.contains("b.txt, line 2") && e.contains("3 fields"), "{e}");
        let e = err("0 0\n# note\n0.5 x\n");
        assert!(
            e.contains("line 3") && e.contains("\"x\" is not a number"),
            "{e}"
        );
        // Not increasing in t.
        let e = err("0 0\n0.5 1\n0.5 0.8\n");
        assert!(
            e.contains("line 3") && e.contains("does not increase"),
            "{e}"
        );
        let e = err("0.6 0\n0.4 1\n");
        assert!(
            e.contains("line 2") && e.contains("does not increase"),
            "{e}"
        );
        // Outside [0, 1], in t or in b.
        let e = err("0 0\n1.5 1\n");
        assert!(e.contains("line 2") && e.contains("outside [0, 1]"), "{e}");
        let e = err("0 -0.1\n1 1\n");
        assert!(e.contains("line 1") && e.contains("outside [0, 1]"), "{e}");
        let e = err("nan 0.5\n1 1\n");
        assert!(e.contains("line 1"), "{e}");
        let e = err("# only a comment\n0.5 0.5\n");
        assert!(e.contains("b.txt: 1 rows"), "{e}");
        let e = Weight::read_table(Path::new("/nonexistent/b.txt"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("/nonexistent/b.txt"), "{e}");
    }
}
