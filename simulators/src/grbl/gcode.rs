//! GRBL's line preprocessing and word parser, and a block interpreter for the subset a
//! single-axis slider needs.

/// GRBL 1.1 status codes used by the emulator (`error:N`).
pub(crate) mod err {
    pub const EXPECTED_COMMAND_LETTER: u8 = 1;
    pub const BAD_NUMBER_FORMAT: u8 = 2;
    pub const INVALID_STATEMENT: u8 = 3;
    pub const NEGATIVE_VALUE: u8 = 4;
    pub const SETTING_DISABLED: u8 = 5;
    pub const IDLE_ERROR: u8 = 8;
    pub const SYSTEM_GC_LOCK: u8 = 9;
    pub const SOFT_LIMIT_ERROR: u8 = 10;
    pub const OVERFLOW: u8 = 11;
    pub const TRAVEL_EXCEEDED: u8 = 15;
    pub const INVALID_JOG_COMMAND: u8 = 16;
    pub const UNSUPPORTED_COMMAND: u8 = 20;
    pub const MODAL_GROUP_VIOLATION: u8 = 21;
    pub const UNDEFINED_FEED_RATE: u8 = 22;
    pub const WORD_REPEATED: u8 = 25;
    pub const INVALID_LINE_NUMBER: u8 = 27;
    pub const VALUE_WORD_MISSING: u8 = 28;
    pub const AXIS_WORDS_EXIST: u8 = 31;
    pub const UNUSED_WORDS: u8 = 36;
}

/// GRBL's `LINE_BUFFER_SIZE` is 80: at most 79 characters survive preprocessing.
pub(crate) const MAX_LINE: usize = 79;

/// Preprocess a raw line as GRBL's protocol loop does: drop whitespace and control characters,
/// `(...)` comments, `;` comments and block delete `/`, upper-case letters.
pub(crate) fn clean(raw: &[u8]) -> Vec<u8> {
    let mut out = Vec::with_capacity(raw.len());
    let mut paren = false;
    for &c in raw {
        if paren {
            if c == b')' {
                paren = false;
            }
            continue;
        }
        match c {
            b'(' => paren = true,
            b';' => break,
            b'/' => {}
            c if c <= b' ' => {}
            c => out.push(c.to_ascii_uppercase()),
        }
    }
    out
}

/// GRBL's `read_float`: optional sign, digits with at most one '.', no exponent.
pub(crate) fn read_float(s: &[u8], i: &mut usize) -> Option<f64> {
    let start = *i;
    let mut j = *i;
    if j < s.len() && (s[j] == b'-' || s[j] == b'+') {
        j += 1;
    }
    let mut digits = 0;
    let mut dot = false;
    while j < s.len() {
        match s[j] {
            b'0'..=b'9' => digits += 1,
            b'.' if !dot => dot = true,
            _ => break,
        }
        j += 1;
    }
    if digits == 0 {
        return None;
    }
    let v: f64 = std::str::from_utf8(&s[start..j]).ok()?.parse().ok()?;
    *i = j;
    Some(v)
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Word {
    pub letter: u8,
    pub value: f64,
}

pub(crate) fn words(line: &[u8]) -> Result<Vec<Word>, u8> {
    let mut out = Vec::new();
    let mut i = 0;
    while i < line.len() {
        let letter = line[i];
        if !letter.is_ascii_uppercase() {
            return Err(err::EXPECTED_COMMAND_LETTER);
        }
        i += 1;
        let value = read_float(line, &mut i).ok_or(err::BAD_NUMBER_FORMAT)?;
        out.push(Word { letter, value });
    }
    Ok(out)
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Motion {
    Seek,
    Linear,
    Cancel,
}

/// Modal state of the g-code parser (what `$G` reports), reset by a soft reset.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct Modal {
    pub motion: Motion,
    pub absolute: bool,
    pub inches: bool,
    /// mm/min; 0 means undefined (GRBL's reset state).
    pub feed: f64,
    pub spindle: f64,
    /// M3/M4 (true) or M5.
    pub spindle_on: bool,
    /// M8 (true) or M9.
    pub flood: bool,
    /// gc_state.position: where the last accepted block ends, mm.
    pub x: f64,
}

impl Modal {
    pub fn new(x: f64) -> Modal {
        Modal {
            motion: Motion::Seek,
            absolute: true,
            inches: false,
            feed: 0.0,
            spindle: 0.0,
            spindle_on: false,
            flood: false,
            x,
        }
    }

    pub fn report(&self) -> String {
        let m = match self.motion {
            Motion::Seek => "G0",
            Motion::Linear => "G1",
            Motion::Cancel => "G80",
        };
        let units = if self.inches { "G20" } else { "G21" };
        let dist = if self.absolute { "G90" } else { "G91" };
        format!(
            "[GC:{m} G54 G17 {units} {dist} G94 {} {} T0 F{} S{}]",
            if self.spindle_on { "M3" } else { "M5" },
            if self.flood { "M8" } else { "M9" },
            self.feed.round(),
            self.spindle.round()
        )
    }
}

/// What a g-code block asks the machine to do, after modal updates.
#[derive(Clone, Debug, PartialEq)]
pub(crate) enum Action {
    None,
    /// Absolute X target (mm) and feed (mm/min; 0 = rapid).
    Move {
        x: f64,
        rapid: bool,
        feed: f64,
    },
    Dwell(f64),
}

#[derive(Default)]
struct Seen {
    groups: u32,
    letters: u32,
}

impl Seen {
    fn group(&mut self, g: u32) -> Result<(), u8> {
        if self.groups & (1 << g) != 0 {
            return Err(err::MODAL_GROUP_VIOLATION);
        }
        self.groups |= 1 << g;
        Ok(())
    }
    fn letter(&mut self, c: u8) -> Result<(), u8> {
        let bit = 1 << (c - b'A');
        if self.letters & bit != 0 {
            return Err(err::WORD_REPEATED);
        }
        self.letters |= bit;
        Ok(())
    }
}

const GROUP_MOTION: u32 = 0;
const GROUP_NONMODAL: u32 = 1;
const GROUP_DISTANCE: u32 = 2;
const GROUP_UNITS: u32 = 3;
const GROUP_PLANE: u32 = 4;
const GROUP_FEEDMODE: u32 = 5;
const GROUP_COORD: u32 = 6;
const GROUP_MISC_G: u32 = 7;
const GROUP_PROGRAM: u32 = 8;
const GROUP_SPINDLE: u32 = 9;
const GROUP_COOLANT: u32 = 10;

fn is_int(v: f64, n: f64) -> bool {
    (v - n).abs() < 1e-4
}

/// Interpret a g-code block (already cleaned, not `$`). On success `modal` is updated and the
/// action to perform is returned; on error `modal` is untouched.
pub(crate) fn interpret(line: &[u8], modal: &mut Modal) -> Result<Action, u8> {
    let ws = words(line)?;
    let mut seen = Seen::default();
    let mut next = modal.clone();
    let mut motion_word = None;
    let mut dwell = false;
    let mut g53 = false;
    let (mut f, mut p, mut x) = (None, None, None);
    let mut axis = false;
    let mut unused = false;
    for w in &ws {
        let v = w.value;
        match w.letter {
            b'G' => {
                let g = if is_int(v, v.round()) {
                    v.round() as i64
                } else {
                    -1
                };
                match g {
                    0 | 1 | 80 => {
                        seen.group(GROUP_MOTION)?;
                        motion_word = Some(match g {
                            0 => Motion::Seek,
                            1 => Motion::Linear,
                            _ => Motion::Cancel,
                        });
                    }
                    4 => {
                        seen.group(GROUP_NONMODAL)?;
                        dwell = true;
                    }
                    53 => {
                        seen.group(GROUP_NONMODAL)?;
                        g53 = true;
                    }
                    90 | 91 => {
                        seen.group(GROUP_DISTANCE)?;
                        next.absolute = g == 90;
                    }
                    20 | 21 => {
                        seen.group(GROUP_UNITS)?;
                        next.inches = g == 20;
                    }
                    17..=19 => seen.group(GROUP_PLANE)?,
                    94 => seen.group(GROUP_FEEDMODE)?,
                    54..=59 => seen.group(GROUP_COORD)?,
                    40 | 61 => seen.group(GROUP_MISC_G)?,
                    // Arcs, probing, G10/G28/G30/G92 offsets, inverse time, tool length:
                    // meaningless for a single-axis slider and not emulated.
                    _ => return Err(err::UNSUPPORTED_COMMAND),
                }
            }
            b'M' => {
                let m = if is_int(v, v.round()) {
                    v.round() as i64
                } else {
                    -1
                };
                match m {
                    0 | 1 | 2 | 30 => seen.group(GROUP_PROGRAM)?,
                    3..=5 => {
                        seen.group(GROUP_SPINDLE)?;
                        next.spindle_on = m != 5;
                    }
                    // M7 (mist) exists only in GRBL builds with ENABLE_M7; the default build
                    // refuses it as an unsupported command.
                    8 | 9 => {
                        seen.group(GROUP_COOLANT)?;
                        next.flood = m == 8;
                    }
                    _ => return Err(err::UNSUPPORTED_COMMAND),
                }
            }
            c @ (b'F' | b'N' | b'P' | b'S' | b'T') => {
                seen.letter(c)?;
                if v < 0.0 {
                    return Err(err::NEGATIVE_VALUE);
                }
                match c {
                    b'F' => f = Some(v),
                    b'P' => p = Some(v),
                    b'S' => next.spindle = v,
                    b'N' if v > 9_999_999.0 => return Err(err::INVALID_LINE_NUMBER),
                    _ => {}
                }
            }
            c @ (b'X' | b'Y' | b'Z') => {
                seen.letter(c)?;
                axis = true;
                if c == b'X' {
                    x = Some(v);
                }
            }
            c @ (b'I' | b'J' | b'K' | b'R' | b'L') => {
                seen.letter(c)?;
                unused = true;
            }
            _ => return Err(err::UNSUPPORTED_COMMAND),
        }
    }
    let scale = if next.inches { 25.4 } else { 1.0 };
    if let Some(f) = f {
        next.feed = f * scale;
    }
    if let Some(m) = motion_word {
        next.motion = m;
    }
    if unused || (p.is_some() && !dwell) {
        return Err(err::UNUSED_WORDS);
    }
    if dwell {
        let p = p.ok_or(err::VALUE_WORD_MISSING)?;
        if axis {
            // GRBL would dwell and then move; a combined block is not emulated.
            return Err(err::AXIS_WORDS_EXIST);
        }
        *modal = next;
        return Ok(Action::Dwell(p));
    }
    let explicit_motion = motion_word.is_some() || axis;
    let action = if explicit_motion {
        match next.motion {
            Motion::Cancel if axis => return Err(err::AXIS_WORDS_EXIST),
            Motion::Cancel => Action::None,
            Motion::Linear if next.feed <= 0.0 => return Err(err::UNDEFINED_FEED_RATE),
            m => match x {
                Some(xv) => {
                    let xv = xv * scale;
                    let target = if g53 || next.absolute {
                        xv
                    } else {
                        modal.x + xv
                    };
                    Action::Move {
                        x: target,
                        rapid: m == Motion::Seek,
                        feed: next.feed,
                    }
                }
                None => Action::None,
            },
        }
    } else {
        if g53 {
            return Err(err::UNSUPPORTED_COMMAND);
        }
        Action::None
    };
    if let Action::Move { x, .. } = action {
        next.x = x;
    }
    *modal = next;
    Ok(action)
}

/// A parsed `$J=` jog line (the part after `=`, cleaned): absolute X target (or None for a jog
/// that only names Y/Z) and feed, mm/min. The parser's modal state is not changed.
pub(crate) fn interpret_jog(line: &[u8], modal: &Modal) -> Result<(Option<f64>, f64), u8> {
    let ws = words(line)?;
    let mut seen = Seen::default();
    let mut absolute = modal.absolute;
    let mut inches = modal.inches;
    let mut g53 = false;
    let (mut f, mut x) = (None, None);
    let mut axis = false;
    for w in &ws {
        let v = w.value;
        match w.letter {
            b'G' => {
                let g = if is_int(v, v.round()) {
                    v.round() as i64
                } else {
                    -1
                };
                match g {
                    90 | 91 => {
                        seen.group(GROUP_DISTANCE)?;
                        absolute = g == 90;
                    }
                    20 | 21 => {
                        seen.group(GROUP_UNITS)?;
                        inches = g == 20;
                    }
                    53 => {
                        seen.group(GROUP_NONMODAL)?;
                        g53 = true;
                    }
                    _ => return Err(err::INVALID_JOG_COMMAND),
                }
            }
            c @ (b'X' | b'Y' | b'Z') => {
                seen.letter(c)?;
                axis = true;
                if c == b'X' {
                    x = Some(v);
                }
            }
            b'F' => {
                seen.letter(b'F')?;
                if w.value < 0.0 {
                    return Err(err::NEGATIVE_VALUE);
                }
                f = Some(v);
            }
            b'N' => seen.letter(b'N')?,
            _ => return Err(err::INVALID_JOG_COMMAND),
        }
    }
    let scale = if inches { 25.4 } else { 1.0 };
    let f = match f {
        Some(f) if f > 0.0 => f * scale,
        _ => return Err(err::UNDEFINED_FEED_RATE),
    };
    if !axis {
        return Err(err::INVALID_JOG_COMMAND);
    }
    let target = x.map(|xv| {
        let xv = xv * scale;
        if g53 || absolute {
            xv
        } else {
            modal.x + xv
        }
    });
    Ok((target, f))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cleans_like_grbl() {
        assert_eq!(clean(b"g1 x10 (comment) f100 ; tail"), b"G1X10F100");
        assert_eq!(clean(b"  \t"), b"");
    }

    #[test]
    fn parse_errors() {
        let mut m = Modal::new(0.0);
        assert_eq!(interpret(b"1X", &mut m), Err(1));
        assert_eq!(interpret(b"GX", &mut m), Err(2));
        assert_eq!(interpret(b"G1X10", &mut m), Err(22));
        assert_eq!(interpret(b"G0G1X1", &mut m), Err(21));
        assert_eq!(interpret(b"X1X2", &mut m), Err(25));
        assert_eq!(interpret(b"G2X1", &mut m), Err(20));
        assert_eq!(interpret(b"G4", &mut m), Err(28));
        assert_eq!(interpret(b"F-1", &mut m), Err(4));
        assert_eq!(m, Modal::new(0.0), "errors leave the modal state alone");
    }

    #[test]
    fn modal_motion() {
        let mut m = Modal::new(0.0);
        assert_eq!(
            interpret(b"G1X10F600", &mut m),
            Ok(Action::Move {
                x: 10.0,
                rapid: false,
                feed: 600.0
            })
        );
        assert_eq!(
            interpret(b"G91X5", &mut m),
            Ok(Action::Move {
                x: 15.0,
                rapid: false,
                feed: 600.0
            })
        );
        assert_eq!(interpret(b"G90", &mut m), Ok(Action::None));
        assert_eq!(interpret(b"G4P0.5", &mut m), Ok(Action::Dwell(0.5)));
        assert_eq!(interpret_jog(b"G91X-5F100", &m), Ok((Some(10.0), 100.0)));
        assert_eq!(interpret_jog(b"X5", &m), Err(22));
        assert_eq!(interpret_jog(b"G1X5F100", &m), Err(16));
    }
}
