//! The kinds of real laser line the default detector missed (issue 34), made by the simulator
//! (`footscan_sim::render::render_kind`): a white-centred saturated line in a colour camera's
//! R - (G + B) / 2, a wide speckled line with a glow, a line along a chessboard's edges stored
//! with JPEG's 2 x 2 colour blocks, a line curved by the lens on a textured board. Per kind,
//! regions drawn from the kind's ranges; per region and detector, the share of lit rows found
//! (a line accepted) and the RMS error against the truth over them (every found row counts:
//! a row locked onto a board edge is an error, not a miss). The targets: at
//! least 98 % of lit rows found in 95 % of regions, and bezier-plus within 5 % of the most
//! accurate of cog, steger, gaussian, blais-rioux and parabolic in 95 % of regions.

use footscan::detect::{self, DetectParams, LinePeak};
use footscan_hal::{Frame, Pixels, Timestamp};
use footscan_sim::render::{render_kind, LineKind};

const W: usize = 400;
const H: usize = 160;
const REGIONS: u64 = 20;
const BASELINES: [&str; 5] = ["cog", "steger", "gaussian", "blais-rioux", "parabolic"];

struct Score {
    found_pct: f64,
    rms_px: f64,
    /// Lit rows missed, by reason.
    missed: std::collections::BTreeMap<&'static str, usize>,
}

fn score(name: &str, f: &footscan_sim::render::KindFrame) -> Score {
    let mut det = detect::build(name, &DetectParams::default()).unwrap();
    let frame = Frame::new(
        0,
        Timestamp::default(),
        f.width as u32,
        f.height as u32,
        Pixels::Gray8(f.pixels.clone()),
    );
    let mut out = vec![LinePeak::NONE; f.height];
    det.detect(&frame, &mut out);
    let (mut lit, mut found, mut sq) = (0usize, 0usize, 0.0);
    let mut missed = std::collections::BTreeMap::new();
    for ((p, &t), &l) in out.iter().zip(&f.truth).zip(&f.lit) {
        if !l {
            continue;
        }
        lit += 1;
        if p.is_valid() {
            found += 1;
            sq += (p.col - t).powi(2);
        } else {
            let why = p.reject.map_or("subpixel", |r| r.as_str());
            *missed.entry(why).or_insert(0) += 1;
        }
    }
    Score {
        found_pct: 100.0 * found as f64 / lit.max(1) as f64,
        rms_px: if found > 0 {
            (sq / found as f64).sqrt()
        } else {
            f64::INFINITY
        },
        missed,
    }
}

/// Per region: bezier-plus's score, the best baseline's RMS and name.
fn kind_table(kind: LineKind) -> Vec<(Score, f64, &'static str)> {
    (0..REGIONS)
        .map(|seed| {
            let f = render_kind(kind, W, H, seed);
            let ours = score("bezier-plus", &f);
            let (best, who) = BASELINES
                .iter()
                .map(|b| (score(b, &f), *b))
                .map(|(s, b)| (s.rms_px, b))
                .fold(
                    (f64::INFINITY, "none"),
                    |a, b| if b.0 < a.0 { b } else { a },
                );
            (ours, best, who)
        })
        .collect()
}

/// Regions (of [`REGIONS`]) where bezier-plus must find >= 98 % of the lit rows, and where it
/// must be within 5 % of the best baseline's RMS: the target (19 of 20) where it is met, else
/// the figure as it stands so a regression shows.
fn check(kind: LineKind, found_min: usize, close_min: usize) {
    let t = kind_table(kind);
    let mut found_ok = 0;
    let mut close_ok = 0;
    for (k, (ours, best, who)) in t.iter().enumerate() {
        let (found, rms) = (&ours.found_pct, &ours.rms_px);
        println!(
            "{} region {k}: bezier-plus {found:.1} % found, {rms:.4} px; best baseline {who} \
             {best:.4} px ({:.2}x); missed {:?}",
            kind.name(),
            rms / best,
            ours.missed
        );
        found_ok += (*found >= 98.0) as usize;
        close_ok += (*rms <= 1.05 * best) as usize;
    }
    println!(
        "{}: found >= 98 % in {found_ok}/{}, within 5 % in {close_ok}/{}",
        kind.name(),
        t.len(),
        t.len()
    );
    assert!(found_ok >= found_min, "{}: found", kind.name());
    assert!(close_ok >= close_min, "{}: accuracy", kind.name());
}

#[test]
fn saturated_colour_line_with_a_white_centre() {
    // Target met (20 and 20 of 20, 0.43-0.50x cog's RMS in the two regions that miss 1-2
    // rows). With the colour difference at full scale where the laser clips but before a
    // clipped run continuing the line above stopped counting as a specular spike, and with a
    // weaker leak into green and blue (0.22-0.3): 15 of 20 found.
    check(LineKind::SaturatedColour, 19, 19);
}

#[test]
fn wide_speckled_line_with_a_glow() {
    // Short of the target: 17 of 20 regions found (misses: rows clipped over more than half
    // the line's width, saturated), 15 of 20 within 5 % of cog, which the bridged run above
    // the threshold helps more (0.82-1.51x its RMS). Before the half-height width and the run
    // crossed speckle dips: 10 and 16 of 20, with cog's RMS 1.5-2x today's.
    check(LineKind::WideSpeckled, 17, 15);
}

#[test]
fn line_along_chessboard_edges_through_jpeg_colour_blocks() {
    // Short of the target: 14 of 20 regions found (13 before a row under the threshold was
    // read on its local background near the line above; the misses: a line on a black square
    // under the row level the white squares set, in rows with no line just above), 5 within
    // 5 % of the best baseline (1.00-3.40x; none, 1.06-3.67x, before the window was clipped
    // at a textured board's level, method.md 4.11). Asserted as it stands.
    check(LineKind::Chessboard, 13, 5);
}

#[test]
fn line_curved_by_the_lens_on_a_textured_board() {
    // Target met: 20 and 20 of 20 (0.39-0.82x the best baseline's RMS, cog every time).
    check(LineKind::LensCurved, 19, 19);
}
