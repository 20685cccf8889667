//! Classification of the lines a GRBL 1.1 controller sends, and the status report parser.

use footscan_hal::SliderState;

/// A parsed `<...>` status report.
#[derive(Clone, Debug, PartialEq)]
pub struct StatusReport {
    pub state: SliderState,
    /// The sub-state after the colon (`Hold:0` → 0, `Hold:1` → 1, `Door:N`).
    pub substate: Option<u8>,
    pub mpos: Option<Vec<f64>>,
    pub wpos: Option<Vec<f64>>,
    pub wco: Option<Vec<f64>>,
    /// Current feed, mm/min (`FS:` or `F:`).
    pub feed: Option<f64>,
    pub spindle: Option<f64>,
    /// `Bf:` planner blocks and RX bytes available.
    pub buffer: Option<(u32, u32)>,
    /// `A:` accessory outputs lit (`S` spindle CW, `C` CCW, `F` flood, `M` mist). GRBL sends
    /// the field only with `Ov:` (every 10-20 reports, and in the first report after an
    /// output changes), so None means "not reported", and `Ov:` without `A:` means all off.
    pub accessories: Option<String>,
}

impl StatusReport {
    /// Machine X: `MPos`, or `WPos + WCO` with the given work offset.
    pub fn machine_x(&self, wco: Option<&[f64]>) -> Option<f64> {
        if let Some(m) = &self.mpos {
            return m.first().copied();
        }
        let w = self.wpos.as_ref()?.first().copied()?;
        let o = self
            .wco
            .as_deref()
            .or(wco)
            .and_then(|o| o.first().copied())
            .unwrap_or(0.0);
        Some(w + o)
    }
}

/// One line from the controller.
#[derive(Clone, Debug, PartialEq)]
pub enum Message {
    Ok,
    Error(u32),
    Alarm(u32),
    Status(StatusReport),
    /// `Grbl 1.1h ['$' for help]`: the controller (re)started.
    Banner(String),
    /// `[MSG:...]`, `[GC:...]`, `[VER:...]`, `[OPT:...]`, `[HLP:...]`, `[echo:...]`, `[G54:...]`
    /// and the like, without the brackets.
    Feedback(String),
    /// `$N=value`.
    Setting(u32, f64),
    /// `$N0=...` startup lines, `>...:ok` startup line execution reports.
    Other(String),
    /// Anything a GRBL 1.1 controller would not send.
    Garbage(String),
}

fn floats(s: &str) -> Option<Vec<f64>> {
    s.split(',').map(|v| v.trim().parse().ok()).collect()
}

/// Parse the inside of a status report line (`<...>` included).
pub fn parse_status(line: &str) -> Result<StatusReport, String> {
    let inner = line
        .strip_prefix('<')
        .and_then(|l| l.strip_suffix('>'))
        .ok_or_else(|| format!("not a status report: {line:?}"))?;
    let mut fields = inner.split('|');
    let word = fields.next().unwrap_or("");
    let state = SliderState::parse(word)
        .ok_or_else(|| format!("unknown machine state {word:?} in {line:?}"))?;
    let substate = word.split_once(':').and_then(|(_, s)| s.parse().ok());
    let mut r = StatusReport {
        state,
        substate,
        mpos: None,
        wpos: None,
        wco: None,
        feed: None,
        spindle: None,
        buffer: None,
        accessories: None,
    };
    let bad = |f: &str| format!("malformed field {f:?} in {line:?}");
    for f in fields {
        let (key, val) = f.split_once(':').unwrap_or((f, ""));
        match key {
            "MPos" => r.mpos = Some(floats(val).ok_or_else(|| bad(f))?),
            "WPos" => r.wpos = Some(floats(val).ok_or_else(|| bad(f))?),
            "WCO" => r.wco = Some(floats(val).ok_or_else(|| bad(f))?),
            "FS" => {
                let v = floats(val)
                    .filter(|v| !v.is_empty())
                    .ok_or_else(|| bad(f))?;
                r.feed = Some(v[0]);
                r.spindle = v.get(1).copied();
            }
            "F" => r.feed = Some(val.trim().parse().map_err(|_| bad(f))?),
            "Bf" => {
                let v = floats(val).filter(|v| v.len() == 2).ok_or_else(|| bad(f))?;
                r.buffer = Some((v[0] as u32, v[1] as u32));
            }
            "Ov" if r.accessories.is_none() => r.accessories = Some(String::new()),
            "A" => r.accessories = Some(val.trim().to_string()),
            // Ln, Pn and future fields carry nothing the slider needs.
            _ => {}
        }
    }
    match r.mpos.as_ref().or(r.wpos.as_ref()) {
        Some(p) if !p.is_empty() => {}
        _ => return Err(format!("status report without a position: {line:?}")),
    }
    Ok(r)
}

fn code(s: &str) -> Option<u32> {
    s.trim().parse().ok()
}

/// Classify one line (without its line terminator).
pub fn parse_line(line: &str) -> Message {
    let l = line.trim();
    if l == "ok" {
        return Message::Ok;
    }
    if let Some(c) = l.strip_prefix("error:").and_then(code) {
        return Message::Error(c);
    }
    if let Some(c) = l.strip_prefix("ALARM:").and_then(code) {
        return Message::Alarm(c);
    }
    if l.starts_with('<') {
        return match parse_status(l) {
            Ok(r) => Message::Status(r),
            Err(_) => Message::Garbage(l.to_string()),
        };
    }
    if l.starts_with("Grbl ") {
        return Message::Banner(l.to_string());
    }
    if let Some(inner) = l.strip_prefix('[').and_then(|s| s.strip_suffix(']')) {
        return Message::Feedback(inner.to_string());
    }
    if let Some(rest) = l.strip_prefix('$') {
        if let Some((k, v)) = rest.split_once('=') {
            if let (Ok(k), Ok(v)) = (k.parse::<u32>(), v.trim().parse::<f64>()) {
                return Message::Setting(k, v);
            }
            if k.starts_with('N') {
                return Message::Other(l.to_string());
            }
        }
    }
    if l.starts_with('>') {
        return Message::Other(l.to_string());
    }
    Message::Garbage(l.to_string())
}

/// The version word of a banner, e.g. `1.1h` from `Grbl 1.1h ['$' for help]`.
pub fn banner_version(banner: &str) -> Option<&str> {
    banner.strip_prefix("Grbl ")?.split_whitespace().next()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn classifies_lines() {
        assert_eq!(parse_line("ok\r"), Message::Ok);
        assert_eq!(parse_line("error:22"), Message::Error(22));
        assert_eq!(parse_line("ALARM:2"), Message::Alarm(2));
        assert_eq!(
            parse_line("Grbl 1.1h ['$' for help]"),
            Message::Banner("Grbl 1.1h ['$' for help]".into())
        );
        assert_eq!(
            parse_line("[MSG:'$H'|'$X' to unlock]"),
            Message::Feedback("MSG:'$H'|'$X' to unlock".into())
        );
        assert_eq!(parse_line("$110=3000.000"), Message::Setting(110, 3000.0));
        assert_eq!(parse_line("$N0="), Message::Other("$N0=".into()));
        assert_eq!(parse_line(">G54:ok"), Message::Other(">G54:ok".into()));
        assert!(matches!(parse_line("\u{fffd}x"), Message::Garbage(_)));
        assert!(matches!(
            parse_line("<Bogus|MPos:1,2,3>"),
            Message::Garbage(_)
        ));
        assert_eq!(banner_version("Grbl 1.1h ['$' for help]"), Some("1.1h"));
    }

    #[test]
    fn parses_status_reports() {
        let r = parse_status("<Hold:1|MPos:12.345,0.000,0.000|FS:1500,0|WCO:1.000,0.000,0.000>")
            .unwrap();
        assert_eq!(r.state, SliderState::Hold);
        assert_eq!(r.substate, Some(1));
        assert_eq!(r.machine_x(None), Some(12.345));
        assert_eq!(r.feed, Some(1500.0));
        let r = parse_status("<Run|WPos:10.000,0.000,0.000|Bf:15,128|F:500>").unwrap();
        assert_eq!(r.machine_x(Some(&[2.5, 0.0, 0.0])), Some(12.5));
        assert_eq!(r.buffer, Some((15, 128)));
        assert_eq!(r.feed, Some(500.0));
        let r = parse_status("<Idle|WPos:1.0,0,0|WCO:-1.0,0,0|Ov:100,100,100>").unwrap();
        assert_eq!(r.machine_x(None), Some(0.0));
        assert_eq!(
            r.accessories.as_deref(),
            Some(""),
            "Ov: without A: is all off"
        );
        let r =
            parse_status("<Idle|MPos:5.380,0.000,-1.000|FS:0,500|Pn:PXYZRHS|Ov:100,100,100|A:S>")
                .unwrap();
        assert_eq!(
            (r.accessories.as_deref(), r.spindle),
            (Some("S"), Some(500.0))
        );
        let r = parse_status("<Idle|MPos:0,0,0|FS:0,0>").unwrap();
        assert_eq!(r.accessories, None, "not reported");
        assert!(parse_status("<Idle|FS:0,0>").is_err());
        assert!(parse_status("<Idle|MPos:1,x,3>").is_err());
        assert!(
            parse_status("<Idle,MPos:0.000,0.000,0.000>").is_err(),
            "GRBL 0.9"
        );
    }
}
