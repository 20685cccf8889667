//! Foot-to-last comfort rules as data: a TOML file by curve type I-IV and rule I-A ... IV.
//!
//! Each rule names the curve it deforms (`curve`, checked against its type) and gives its
//! values per shoe type or wearer; every value table has a `source` line saying where it
//! comes from. Unknown rules, curves, shoe types, wearers or fields are errors that name the
//! line (the TOML parser's span), so a typo never silently falls back to a default.
//! The documented default file is `config/last-rules.toml`.

use serde::{Deserialize, Serialize};
use std::path::Path;

/// The shoe types the rules distinguish (rule I-E and the laced/pump rule of II-F).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Shoe {
    Dress,
    Sport,
    Football,
    Hiking,
    Casual,
}

impl std::str::FromStr for Shoe {
    type Err = RulesError;
    fn from_str(s: &str) -> Result<Shoe, RulesError> {
        match s {
            "dress" | "leather" => Ok(Shoe::Dress),
            "sport" => Ok(Shoe::Sport),
            "football" => Ok(Shoe::Football),
            "hiking" => Ok(Shoe::Hiking),
            "casual" => Ok(Shoe::Casual),
            _ => Err(RulesError::Shoe(s.to_string())),
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Wearer {
    Man,
    Woman,
    Child,
}

impl std::str::FromStr for Wearer {
    type Err = RulesError;
    fn from_str(s: &str) -> Result<Wearer, RulesError> {
        match s {
            "man" => Ok(Wearer::Man),
            "woman" => Ok(Wearer::Woman),
            "child" => Ok(Wearer::Child),
            _ => Err(RulesError::Wearer(s.to_string())),
        }
    }
}

/// The characteristic curves, with their deformation type.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Curve {
    /// Type I.
    BottomOutline,
    /// Type II.
    BallGirth,
    InstepGirth,
    LongHeelGirth,
    /// Type III.
    SideProfile,
    /// Type IV.
    AnkleGirth,
}

impl Curve {
    pub fn kind(self) -> u8 {
        match self {
            Curve::BottomOutline => 1,
            Curve::BallGirth | Curve::InstepGirth | Curve::LongHeelGirth => 2,
            Curve::SideProfile => 3,
            Curve::AnkleGirth => 4,
        }
    }
    pub fn name(self) -> &'static str {
        match self {
            Curve::BottomOutline => "bottom_outline",
            Curve::BallGirth => "ball_girth",
            Curve::InstepGirth => "instep_girth",
            Curve::LongHeelGirth => "long_heel_girth",
            Curve::SideProfile => "side_profile",
            Curve::AnkleGirth => "ankle_girth",
        }
    }
}

/// A value per shoe type (mm).
#[derive(Clone, Copy, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct PerShoe {
    pub dress: f64,
    pub sport: f64,
    pub football: f64,
    pub hiking: f64,
    pub casual: f64,
}

impl PerShoe {
    pub fn get(&self, s: Shoe) -> f64 {
        match s {
            Shoe::Dress => self.dress,
            Shoe::Sport => self.sport,
            Shoe::Football => self.football,
            Shoe::Hiking => self.hiking,
            Shoe::Casual => self.casual,
        }
    }
}

/// A value per wearer (mm).
#[derive(Clone, Copy, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct PerWearer {
    pub man: f64,
    pub woman: f64,
    pub child: f64,
}

impl PerWearer {
    pub fn get(&self, w: Wearer) -> f64 {
        match w {
            Wearer::Man => self.man,
            Wearer::Woman => self.woman,
            Wearer::Child => self.child,
        }
    }
}

/// I-A: bottom length = foot length + toe allowance - heel allowance.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct BottomLength {
    pub curve: Curve,
    pub toe_allowance_mm: PerShoe,
    /// Added to the toe allowance per wearer (growth room for children).
    pub toe_allowance_extra_mm: PerWearer,
    pub heel_allowance_mm: PerShoe,
    pub source: String,
}

/// I-B, I-C, I-D: a width change (mm) on the bottom outline.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct WidthRule {
    pub curve: Curve,
    pub change_mm: f64,
    pub source: String,
}

/// I-E: the bottom widths changed by shoe type (added to I-B, I-C and I-D).
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct ShoeWidth {
    pub curve: Curve,
    pub change_mm: PerShoe,
    pub source: String,
}

/// II-F: ball girth change by wearer, shoe type (laced larger, pumps smaller) and heel
/// height.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct BallGirth {
    pub curve: Curve,
    pub change_mm: PerWearer,
    pub shoe_change_mm: PerShoe,
    /// Added per 10 mm of heel height above `heel_reference_mm`.
    pub per_10mm_heel_mm: f64,
    pub heel_reference_mm: f64,
    pub source: String,
}

/// II-G, II-H, IV: a girth change (mm).
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct GirthRule {
    pub curve: Curve,
    pub change_mm: f64,
    pub source: String,
}

/// III: the side profile follows the nodes of types I and II (no size of its own).
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct ProfileRule {
    pub curve: Curve,
    pub source: String,
}

/// The rule set.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct RuleSet {
    #[serde(rename = "I-A")]
    pub i_a: BottomLength,
    #[serde(rename = "I-B")]
    pub i_b: WidthRule,
    #[serde(rename = "I-C")]
    pub i_c: WidthRule,
    #[serde(rename = "I-D")]
    pub i_d: WidthRule,
    #[serde(rename = "I-E")]
    pub i_e: ShoeWidth,
    #[serde(rename = "II-F")]
    pub ii_f: BallGirth,
    #[serde(rename = "II-G")]
    pub ii_g: GirthRule,
    #[serde(rename = "II-H")]
    pub ii_h: GirthRule,
    #[serde(rename = "III")]
    pub iii: ProfileRule,
    #[serde(rename = "IV")]
    pub iv: GirthRule,
}

/// Why a rule file, a shoe type or a wearer was refused; each names the input and what is
/// valid.
#[derive(Debug, thiserror::Error)]
pub enum RulesError {
    #[error("unknown shoe type {0:?}; valid: dress (leather), sport, football, hiking, casual")]
    Shoe(String),
    #[error("unknown wearer {0:?}; valid: man, woman, child")]
    Wearer(String),
    #[error("{}: cannot read the rule file", path.display())]
    Read {
        path: std::path::PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// TOML's own message without its source excerpt; `line` when TOML knows it.
    #[error("{name}: {}{message}", line.map(|l| format!("line {l}: ")).unwrap_or_default())]
    Toml {
        name: String,
        line: Option<usize>,
        message: String,
    },
    #[error("{name}: line {line}: rule {rule} acts on {expected}, not on {got}")]
    WrongCurve {
        name: String,
        line: usize,
        rule: &'static str,
        expected: &'static str,
        got: &'static str,
    },
}

/// The file that ships with the crate's documentation (`config/last-rules.toml`).
pub const DEFAULT_RULES: &str = include_str!("../../../../config/last-rules.toml");

impl RuleSet {
    /// Parse a rule file; `name` names it in errors.
    pub fn parse(text: &str, name: &str) -> Result<RuleSet, RulesError> {
        let r: RuleSet = toml::from_str(text).map_err(|e| RulesError::Toml {
            name: name.to_string(),
            line: e
                .span()
                .map(|s| text[..s.start.min(text.len())].lines().count().max(1)),
            message: e.message().to_string(),
        })?;
        // Each rule's curve must be one of its type.
        let checks: [(&str, Curve, &[Curve]); 10] = [
            ("I-A", r.i_a.curve, &[Curve::BottomOutline]),
            ("I-B", r.i_b.curve, &[Curve::BottomOutline]),
            ("I-C", r.i_c.curve, &[Curve::BottomOutline]),
            ("I-D", r.i_d.curve, &[Curve::BottomOutline]),
            ("I-E", r.i_e.curve, &[Curve::BottomOutline]),
            ("II-F", r.ii_f.curve, &[Curve::BallGirth]),
            ("II-G", r.ii_g.curve, &[Curve::InstepGirth]),
            ("II-H", r.ii_h.curve, &[Curve::LongHeelGirth]),
            ("III", r.iii.curve, &[Curve::SideProfile]),
            ("IV", r.iv.curve, &[Curve::AnkleGirth]),
        ];
        for (rule, c, ok) in checks {
            if !ok.contains(&c) {
                return Err(RulesError::WrongCurve {
                    name: name.to_string(),
                    line: find_line(text, rule),
                    rule,
                    expected: ok[0].name(),
                    got: c.name(),
                });
            }
        }
        Ok(r)
    }
    pub fn load(path: &Path) -> Result<RuleSet, RulesError> {
        let text = std::fs::read_to_string(path).map_err(|source| RulesError::Read {
            path: path.to_path_buf(),
            source,
        })?;
        RuleSet::parse(&text, &path.display().to_string())
    }
    pub fn default_rules() -> RuleSet {
        RuleSet::parse(DEFAULT_RULES, "config/last-rules.toml").expect("default rules parse")
    }
}

fn find_line(text: &str, rule: &str) -> usize {
    let head = format!("[\"{rule}\"]");
    let head2 = format!("[{rule}]");
    text.lines()
        .position(|l| l.trim() == head || l.trim() == head2)
        .map(|i| i + 1)
        .unwrap_or(0)
}
