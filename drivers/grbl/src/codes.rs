//! GRBL 1.1 error and alarm code meanings (from the GRBL 1.1 interface documentation).

/// Meaning of `error:N`.
pub fn error_message(code: u32) -> &'static str {
    match code {
        1 => "expected command letter: G-code words consist of a letter and a value; letter was not found",
        2 => "bad number format: missing the expected G-code word value or numeric value format is not valid",
        3 => "invalid statement: Grbl '$' system command was not recognized or supported",
        4 => "value < 0: negative value received for an expected positive value",
        5 => "setting disabled: homing cycle is not enabled via settings",
        6 => "value < 3 usec: minimum step pulse time must be greater than 3 usec",
        7 => "EEPROM read fail: using defaults",
        8 => "not idle: Grbl '$' command cannot be used unless Grbl is IDLE",
        9 => "G-code lock: G-code commands are locked out during alarm or jog state",
        10 => "homing not enabled: soft limits cannot be enabled without homing also enabled",
        11 => "line overflow: max characters per line exceeded; line was not executed",
        12 => "step rate > 30 kHz: '$' setting value causes the step rate to exceed the maximum supported",
        13 => "check door: safety door detected as opened and door state initiated",
        14 => "line length exceeded: build info or startup line exceeded EEPROM line length limit",
        15 => "travel exceeded: jog target exceeds machine travel; jog command has been ignored",
        16 => "invalid jog command: jog command has no '=' or contains prohibited g-code",
        17 => "setting disabled: laser mode requires PWM output",
        20 => "unsupported command: unsupported or invalid g-code command found in block",
        21 => "modal group violation: more than one g-code command from the same modal group found in block",
        22 => "undefined feed rate: feed rate has not yet been set or is undefined",
        23 => "G-code command in block requires an integer value",
        24 => "more than one g-code command that requires axis words found in block",
        25 => "repeated g-code word found in block",
        26 => "no axis words found in block for g-code command or current modal state which requires them",
        27 => "line number value is invalid",
        28 => "G-code command is missing a required value word",
        29 => "G59.x work coordinate systems are not supported",
        30 => "G53 only allowed with G0 and G1 motion modes",
        31 => "axis words found in block when no command or current modal state uses them",
        32 => "G2 and G3 arcs require at least one in-plane axis word",
        33 => "motion command target is invalid",
        34 => "arc radius value is invalid",
        35 => "G2 and G3 arcs require at least one in-plane offset word",
        36 => "unused value words found in block",
        37 => "G43.1 dynamic tool length offset is not assigned to configured tool length axis",
        38 => "tool number greater than max supported value",
        _ => "unknown error code",
    }
}

/// Meaning of `ALARM:N`. Code 0 is this driver's own: the controller reported the alarm lock
/// (`[MSG:'$H'|'$X' to unlock]` or an `Alarm` state) without an `ALARM:N` line.
pub fn alarm_message(code: u32) -> &'static str {
    match code {
        0 => "alarm lock (after power-up, reset or an earlier alarm): home ($H) or unlock ($X)",
        1 => "hard limit triggered; machine position is likely lost due to sudden halt, re-homing is highly recommended",
        2 => "soft limit: G-code motion target exceeds machine travel; machine position retained, alarm may be safely unlocked",
        3 => "reset while in motion; machine position is likely lost due to sudden halt, re-homing is highly recommended",
        4 => "probe fail: probe is not in the expected initial state before starting probe cycle",
        5 => "probe fail: probe did not contact the workpiece within the programmed travel",
        6 => "homing fail: the active homing cycle was reset",
        7 => "homing fail: safety door was opened during homing cycle",
        8 => "homing fail: pull off travel failed to clear limit switch",
        9 => "homing fail: could not find limit switch within search distances",
        _ => "unknown alarm code",
    }
}
