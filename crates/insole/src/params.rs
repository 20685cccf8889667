//! The clinician's parameters: what each means, its default and the range a value must lie
//! in. docs/method.md ("Orthotic insole") says why each default is what it is.

use crate::InsoleError;
use serde::{Deserialize, Serialize};
use std::path::Path;

/// How far the insole reaches toward the toes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Length {
    /// To the toe tip (plus `extra_length_mm`).
    Full,
    /// Ending `three_quarter_behind_mm` behind the line of the first and fifth metatarsal
    /// heads: the forefoot stands on the shoe's own insole.
    ThreeQuarter,
}

/// Which side of the foot a post (wedge) raises.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum PostSide {
    /// Raises the medial side: a varus post (against pronation).
    Medial,
    /// Raises the lateral side: a valgus post (against supination).
    Lateral,
}

/// The insole's parameters, millimetres and degrees. A TOML file holds any of them
/// (`--params P.toml`); the others keep their defaults. Unknown keys are refused.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Params {
    pub length: Length,
    /// Thickness under the weight-bearing sole, top cover included (mm).
    pub base_thickness_mm: f64,
    /// Thickness of the top cover glued on the shell (mm): the mesh is the shell, its top
    /// this far below the surface the foot touches.
    pub top_cover_mm: f64,
    /// Height of the heel cup's rim above the heel seat (the top at the heel centre), mm.
    pub heel_cup_depth_mm: f64,
    /// The insole's arch: its top under the scanned arch point, above the seat at that
    /// station, as a height (mm) ...
    pub arch_height_mm: Option<f64>,
    /// ... or as a share of the scanned arch height (used when `arch_height_mm` is not
    /// given; 1 is total contact).
    pub arch_share: f64,
    /// Rearfoot post: angle of the top across the heel (deg) and the side it raises.
    pub rearfoot_post_deg: f64,
    pub rearfoot_post_side: PostSide,
    /// Forefoot post: angle of the top across the metatarsal heads (deg) and its side.
    pub forefoot_post_deg: f64,
    pub forefoot_post_side: PostSide,
    /// Metatarsal pad: height of its apex (mm, 0 for none) and how far its apex lies behind
    /// the line of the second to fourth metatarsal heads (mm).
    pub met_pad_height_mm: f64,
    pub met_pad_behind_mm: f64,
    /// Depth of the first ray cut-out under the first metatarsal head and the hallux (mm,
    /// 0 for none; full-length insoles only).
    pub first_ray_cutout_mm: f64,
    /// Heel lift: added under the heel, tapering to nothing at the metatarsal heads (mm).
    pub heel_lift_mm: f64,
    /// Length added in front of the toe tip (full length) (mm).
    pub extra_length_mm: f64,
    /// How far a 3/4 insole ends behind the metatarsal heads' line (mm).
    pub three_quarter_behind_mm: f64,
    /// Outline margin beyond the footprint when no shoe bottom is given (mm).
    pub margin_mm: f64,
    /// Cell of the STL / 3MF mesh (mm) and of the faceted STEP solid (mm).
    pub mesh_cell_mm: f64,
    pub step_cell_mm: f64,
}

impl Default for Params {
    fn default() -> Params {
        Params {
            length: Length::Full,
            base_thickness_mm: 3.0,
            top_cover_mm: 1.0,
            heel_cup_depth_mm: 8.0,
            arch_height_mm: None,
            arch_share: 1.0,
            rearfoot_post_deg: 0.0,
            rearfoot_post_side: PostSide::Medial,
            forefoot_post_deg: 0.0,
            forefoot_post_side: PostSide::Medial,
            met_pad_height_mm: 0.0,
            met_pad_behind_mm: 5.0,
            first_ray_cutout_mm: 0.0,
            heel_lift_mm: 0.0,
            extra_length_mm: 0.0,
            three_quarter_behind_mm: 5.0,
            margin_mm: 3.0,
            mesh_cell_mm: 1.0,
            step_cell_mm: 2.0,
        }
    }
}

/// The starting points a clinic picks from (footscand's insole card), by name. Each is the
/// defaults with a few parameters changed; the clinician edits any of them before the job.
pub const PRESETS: [&str; 3] = ["cushioning", "supportive", "correcting"];

impl Params {
    /// Preset `name` of [`PRESETS`]:
    /// - cushioning: a thick soft cover over a thin shell, a shallow cup and 90 % of the
    ///   arch, for a sore or insensitive foot (diabetic, fat pad atrophy): pressure spread,
    ///   nothing pushed;
    /// - supportive: total contact with a deeper cup and a firmer shell, for a tired or
    ///   flexible flat foot that needs holding, not correcting;
    /// - correcting: a deep cup, a 4 deg medial rearfoot post, a 2 deg medial forefoot post,
    ///   the arch raised 10 % and a 3 mm metatarsal pad, for an over-pronating foot with
    ///   forefoot pain.
    ///
    /// None for any other name.
    pub fn preset(name: &str) -> Option<Params> {
        let d = Params::default();
        Some(match name {
            "cushioning" => Params {
                base_thickness_mm: 6.0,
                top_cover_mm: 3.0,
                heel_cup_depth_mm: 6.0,
                arch_share: 0.9,
                ..d
            },
            "supportive" => Params {
                base_thickness_mm: 4.0,
                top_cover_mm: 1.5,
                heel_cup_depth_mm: 12.0,
                ..d
            },
            "correcting" => Params {
                base_thickness_mm: 4.0,
                top_cover_mm: 1.0,
                heel_cup_depth_mm: 15.0,
                arch_share: 1.1,
                rearfoot_post_deg: 4.0,
                rearfoot_post_side: PostSide::Medial,
                forefoot_post_deg: 2.0,
                forefoot_post_side: PostSide::Medial,
                met_pad_height_mm: 3.0,
                ..d
            },
            _ => return None,
        })
    }

    /// A preset (or the defaults) with the keys of `changes` (a JSON object of
    /// [`Params`]' fields) put over it, then checked: the first unknown key or bad value is
    /// named with what would be valid.
    pub fn from_preset_json(
        preset: Option<&str>,
        changes: &serde_json::Map<String, serde_json::Value>,
    ) -> Result<Params, InsoleError> {
        let base = match preset {
            None => Params::default(),
            Some(n) => Params::preset(n).ok_or_else(|| InsoleError::Preset {
                name: n.to_string(),
            })?,
        };
        let mut v = serde_json::to_value(&base).expect("the parameters serialise");
        let obj = v.as_object_mut().expect("the parameters are an object");
        for (k, x) in changes {
            obj.insert(k.clone(), x.clone());
        }
        let p: Params = serde_json::from_value(v)
            .map_err(|e| InsoleError::ParamsJson { why: e.to_string() })?;
        p.validate()?;
        Ok(p)
    }
}

/// The thinnest shell a printer or a mill leaves whole (mm): no correction may cut deeper.
pub const MIN_SHELL_MM: f64 = 1.0;

/// Ranges: (name, value, low, high, why).
type Check = (&'static str, f64, f64, f64, &'static str);

impl Params {
    /// Parameters from a TOML file (missing keys keep their defaults).
    pub fn load(path: &Path) -> Result<Params, InsoleError> {
        let text = std::fs::read_to_string(path).map_err(|source| InsoleError::Read {
            path: path.to_path_buf(),
            source,
        })?;
        toml::from_str(&text).map_err(|e| InsoleError::ParamsFile {
            path: path.to_path_buf(),
            why: e.to_string(),
        })
    }

    /// Every parameter in its range, those that depend on each other included; the foot's
    /// own limits (the pad below the arch) are checked once the foot is known.
    pub fn validate(&self) -> Result<(), InsoleError> {
        let shell = self.base_thickness_mm - self.top_cover_mm;
        let checks: [Check; 15] = [
            ("base_thickness_mm", self.base_thickness_mm, 2.0, 15.0, "an insole thinner than 2 mm breaks, one over 15 mm does not fit a shoe"),
            ("top_cover_mm", self.top_cover_mm, 0.0, (self.base_thickness_mm - MIN_SHELL_MM).max(0.0), "the shell under the cover must stay at least 1 mm thick"),
            ("heel_cup_depth_mm", self.heel_cup_depth_mm, 0.0, 25.0, "a deeper cup does not fit a shoe's heel counter"),
            ("arch_share", self.arch_share, 0.0, 1.5, "1 is total contact; more than half again the scanned arch pushes it up"),
            ("rearfoot_post_deg", self.rearfoot_post_deg, 0.0, 10.0, "posts beyond 10 degrees tip the foot over"),
            ("forefoot_post_deg", self.forefoot_post_deg, 0.0, 10.0, "posts beyond 10 degrees tip the foot over"),
            ("met_pad_height_mm", self.met_pad_height_mm, 0.0, 10.0, "a pad over 10 mm is a bar, not a pad"),
            ("met_pad_behind_mm", self.met_pad_behind_mm, 0.0, 25.0, "the pad lies behind the heads, under the shafts"),
            ("first_ray_cutout_mm", self.first_ray_cutout_mm, 0.0, (shell - MIN_SHELL_MM).max(0.0), "the shell under the cut-out must stay at least 1 mm thick (base thickness less top cover less 1 mm)"),
            ("heel_lift_mm", self.heel_lift_mm, 0.0, 20.0, "larger lifts go in the shoe's heel, not the insole"),
            ("extra_length_mm", self.extra_length_mm, 0.0, 30.0, "more than a shoe's toe allowance"),
            ("three_quarter_behind_mm", self.three_quarter_behind_mm, 0.0, 30.0, "the end must lie between the heads and the midfoot"),
            ("margin_mm", self.margin_mm, 0.0, 15.0, "the outline must stay near the foot"),
            ("mesh_cell_mm", self.mesh_cell_mm, 0.25, 2.0, "finer cells make files of hundreds of MB, coarser ones lose the pad's shape"),
            ("step_cell_mm", self.step_cell_mm, 0.5, 4.0, "finer facets make STEP files a mill's CAM cannot open"),
        ];
        for (name, value, lo, hi, why) in checks {
            if !(value.is_finite() && value >= lo && value <= hi) {
                return Err(InsoleError::Param {
                    name,
                    value,
                    lo,
                    hi,
                    why: why.to_string(),
                });
            }
        }
        if let Some(a) = self.arch_height_mm {
            if !(a.is_finite() && (0.0..=35.0).contains(&a)) {
                return Err(InsoleError::Param {
                    name: "arch_height_mm",
                    value: a,
                    lo: 0.0,
                    hi: 35.0,
                    why: "no foot's arch stands higher than 35 mm".into(),
                });
            }
        }
        if self.length == Length::ThreeQuarter && self.first_ray_cutout_mm > 0.0 {
            return Err(InsoleError::Param {
                name: "first_ray_cutout_mm",
                value: self.first_ray_cutout_mm,
                lo: 0.0,
                hi: 0.0,
                why: "a 3/4 insole ends behind the first metatarsal head: it has no first ray to cut out (length = \"full\" for one)".into(),
            });
        }
        if self.length == Length::ThreeQuarter && self.extra_length_mm > 0.0 {
            return Err(InsoleError::Param {
                name: "extra_length_mm",
                value: self.extra_length_mm,
                lo: 0.0,
                hi: 0.0,
                why: "a 3/4 insole ends behind the metatarsal heads: extra length is for full-length ones".into(),
            });
        }
        Ok(())
    }

    /// The shell's thickness under the weight-bearing sole (mm).
    pub fn shell_mm(&self) -> f64 {
        self.base_thickness_mm - self.top_cover_mm
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_are_valid_and_a_40_degree_post_is_refused_by_name() {
        Params::default().validate().unwrap();
        let p = Params {
            rearfoot_post_deg: 40.0,
            ..Params::default()
        };
        let e = p.validate().unwrap_err().to_string();
        assert!(e.contains("rearfoot_post_deg") && e.contains("10"), "{e}");
        let e = toml::from_str::<Params>("heel_cup_dept_mm = 3").unwrap_err();
        assert!(e.to_string().contains("heel_cup_dept_mm"), "{e}");
        let p: Params =
            toml::from_str("length = \"three_quarter\"\nmet_pad_height_mm = 4").unwrap();
        assert_eq!(p.length, Length::ThreeQuarter);
        assert_eq!(p.met_pad_height_mm, 4.0);
        assert_eq!(p.base_thickness_mm, 3.0);
    }

    #[test]
    fn presets_are_valid_and_changes_are_checked_by_name() {
        for n in PRESETS {
            Params::preset(n).unwrap().validate().unwrap();
        }
        assert!(Params::preset("firm").is_none());
        let mut ch = serde_json::Map::new();
        ch.insert("rearfoot_post_deg".into(), 6.0.into());
        let p = Params::from_preset_json(Some("correcting"), &ch).unwrap();
        assert_eq!((p.rearfoot_post_deg, p.met_pad_height_mm), (6.0, 3.0));
        ch.insert("rearfoot_post_deg".into(), 40.0.into());
        let e = Params::from_preset_json(Some("correcting"), &ch).unwrap_err();
        assert!(e.to_string().contains("rearfoot_post_deg = 40"), "{e}");
        let mut ch = serde_json::Map::new();
        ch.insert("heel_cup".into(), 6.0.into());
        let e = Params::from_preset_json(None, &ch).unwrap_err().to_string();
        assert!(
            e.contains("heel_cup") && e.contains("heel_cup_depth_mm"),
            "{e}"
        );
        let e = Params::from_preset_json(Some("firm"), &serde_json::Map::new()).unwrap_err();
        assert!(e.to_string().contains("cushioning"), "{e}");
    }
}
