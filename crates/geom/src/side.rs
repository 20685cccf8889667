//! Which foot: one type for the scanner, the simulator and the last stages, so a side crosses
//! crate boundaries without a conversion.

use serde::{Deserialize, Serialize};

/// Left or right foot (or the last for it). Serialised lowercase, as every file has it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Side {
    Left,
    Right,
}

impl Side {
    /// "left" or "right", as in the files and the pictures' titles.
    pub fn as_str(self) -> &'static str {
        match self {
            Side::Left => "left",
            Side::Right => "right",
        }
    }

    /// The other foot.
    pub fn other(self) -> Side {
        match self {
            Side::Left => Side::Right,
            Side::Right => Side::Left,
        }
    }
}

impl std::fmt::Display for Side {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.as_str())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn side_names_match_its_serde_form() {
        for s in [Side::Left, Side::Right] {
            let json = serde_json::to_string(&s).unwrap();
            assert_eq!(json, format!("\"{}\"", s.as_str()));
            assert_eq!(serde_json::from_str::<Side>(&json).unwrap(), s);
            assert_eq!(s.other().other(), s);
            assert_ne!(s.other(), s);
        }
    }
}
