//! The grey channel a colour source is reduced to before detection (docs/method.md section 4).
//!
//! It lives in the HAL because colour is reduced where it enters: the V4L2 driver converts a
//! device buffer straight into this channel, and footscan's detect stage does the same for
//! colour files, so both agree pixel for pixel.

use serde::{Deserialize, Serialize};

/// Which grey channel of a colour frame the detectors see.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Deserialize, Serialize)]
#[serde(try_from = "String", into = "String")]
pub enum Channel {
    /// BT.601 luma, (77 R + 150 G + 29 B) / 256; a grey frame as it is.
    Luma,
    Red,
    Green,
    Blue,
    /// max(0, R - (G + B) / 2): a red laser over white, grey and black surfaces.
    RedMinusOthers,
    /// max(0, G - (R + B) / 2): a green laser likewise.
    GreenMinusOthers,
}

/// The names [`Channel::parse`] accepts.
pub const CHANNEL_NAMES: &str =
    "luma, red, green, blue, red-minus-others, green-minus-others (or R, G, B, R-(G+B)/2, G-(R+B)/2)";

impl Channel {
    pub fn parse(s: &str) -> Result<Self, String> {
        Ok(match s.trim() {
            "luma" | "gray" | "grey" | "Y" => Channel::Luma,
            "red" | "R" => Channel::Red,
            "green" | "G" => Channel::Green,
            "blue" | "B" => Channel::Blue,
            "red-minus-others" | "R-(G+B)/2" => Channel::RedMinusOthers,
            "green-minus-others" | "G-(R+B)/2" => Channel::GreenMinusOthers,
            other => return Err(format!("channel = {other:?}: one of {CHANNEL_NAMES}")),
        })
    }

    pub fn as_str(self) -> &'static str {
        match self {
            Channel::Luma => "luma",
            Channel::Red => "red",
            Channel::Green => "green",
            Channel::Blue => "blue",
            Channel::RedMinusOthers => "red-minus-others",
            Channel::GreenMinusOthers => "green-minus-others",
        }
    }

    /// The channel's value of one pixel (in the pixel's own units; never above the largest
    /// of `r`, `g`, `b`).
    #[inline(always)]
    pub fn of(self, r: u32, g: u32, b: u32) -> u32 {
        match self {
            Channel::Luma => (77 * r + 150 * g + 29 * b) >> 8,
            Channel::Red => r,
            Channel::Green => g,
            Channel::Blue => b,
            Channel::RedMinusOthers => r.saturating_sub((g + b) / 2),
            Channel::GreenMinusOthers => g.saturating_sub((r + b) / 2),
        }
    }
}

impl std::fmt::Display for Channel {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.as_str())
    }
}

impl From<Channel> for String {
    fn from(c: Channel) -> String {
        c.as_str().to_string()
    }
}

impl TryFrom<String> for Channel {
    type Error = String;
    fn try_from(s: String) -> Result<Self, String> {
        Channel::parse(&s)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip_and_values() {
        for c in [
            Channel::Luma,
            Channel::Red,
            Channel::Green,
            Channel::Blue,
            Channel::RedMinusOthers,
            Channel::GreenMinusOthers,
        ] {
            assert_eq!(Channel::parse(c.as_str()), Ok(c));
        }
        assert!(Channel::parse("purple")
            .unwrap_err()
            .contains("red-minus-others"));
        assert_eq!(Channel::Luma.of(255, 255, 255), 255);
        assert_eq!(Channel::RedMinusOthers.of(255, 60, 40), 205);
        assert_eq!(Channel::GreenMinusOthers.of(60, 40, 255), 0);
    }
}
