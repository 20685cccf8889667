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

    /// The channel's value of one 8-bit pixel ([`Channel::of_full`] with full scale 255).
    #[inline(always)]
    pub fn of(self, r: u32, g: u32, b: u32) -> u32 {
        self.of_full(r, g, b, 255)
    }

    /// The channel's value of one pixel whose full scale is `full` (never above the largest of
    /// `r`, `g`, `b`).
    ///
    /// A colour difference is full scale wherever the laser's own channel is: a laser bright
    /// enough to clip its channel leaks through the Bayer filter into the other two and clips
    /// them at its centre as well, and there R = G = B = full would make the difference 0 and
    /// split the line in two (docs/method.md section 4.9). Clipped, the laser's channel says
    /// only "at least full scale", so the difference is taken as large as it can be, and
    /// nearly so over the top eighth of the scale.
    #[inline(always)]
    pub fn of_full(self, r: u32, g: u32, b: u32, full: u32) -> u32 {
        match self {
            Channel::Luma => (77 * r + 150 * g + 29 * b) >> 8,
            Channel::Red => r,
            Channel::Green => g,
            Channel::Blue => b,
            Channel::RedMinusOthers => r.saturating_sub((g + b) / 2).max(clipping(r, full)),
            Channel::GreenMinusOthers => g.saturating_sub((r + b) / 2).max(clipping(g, full)),
        }
    }
}

/// How near the laser's channel `v` is to clipping, as a channel value: 0 below 7/8 of full
/// scale, rising to `full` at full scale. A ramp rather than a step: one pixel of a line's
/// white centre clips and its neighbour stops at 250 of 255, and a step would leave the
/// line's profile 255, 6, 255 there.
#[inline(always)]
fn clipping(v: u32, full: u32) -> u32 {
    let knee = full - full / 8;
    if v <= knee {
        0
    } else {
        ((v.min(full) - knee) as u64 * full as u64 / (full - knee) as u64) as u32
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
        assert_eq!(Channel::RedMinusOthers.of(200, 60, 40), 150);
        assert_eq!(Channel::GreenMinusOthers.of(60, 40, 255), 0);
        // A clipped laser channel: full scale, though the others clipped too (a white centre).
        assert_eq!(Channel::RedMinusOthers.of(255, 255, 255), 255);
        assert_eq!(Channel::GreenMinusOthers.of(250, 255, 255), 255);
        assert_eq!(Channel::RedMinusOthers.of_full(255, 255, 255, 65535), 0);
        // Near clipping: a ramp over the top eighth of full scale.
        assert_eq!(Channel::RedMinusOthers.of(250, 244, 244), 213);
        assert_eq!(Channel::RedMinusOthers.of(224, 224, 224), 0);
        assert_eq!(Channel::RedMinusOthers.of(230, 224, 224), 49);
        assert_eq!(
            Channel::RedMinusOthers.of_full(65535, 65535, 0, 65535),
            65535
        );
    }
}
