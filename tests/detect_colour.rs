//! The simulator's colour camera (render.rs, "Colour") through the detectors: a red laser under
//! room light, reduced to a channel as the V4L2 driver reduces a colour format.

use footscan::detect::{self, DetectParams, LinePeak};
use footscan_hal::{Channel, Frame, Pixels, Timestamp};
use footscan_sim::foot::{Foot, FootParams};
use footscan_sim::optics::Optics;
use footscan_sim::render::{ColourCamera, NoiseConfig, Renderer, RowTruth, Scene};

fn renderer(noise: NoiseConfig) -> Renderer {
    let foot = Foot::new(FootParams::default()).unwrap();
    Renderer::new(Optics::default(), noise, Scene::Foot(foot), 11).unwrap()
}

/// Rows with a line in truth, rows found among them, RMS error (px), rows found without one.
fn accuracy(r: &mut Renderer, xs: &[f64]) -> (usize, usize, f64, usize) {
    let mut det = detect::build("bezier-plus", &DetectParams::default()).unwrap();
    let (mut n, mut found, mut sq, mut spurious) = (0, 0, 0.0, 0);
    for (k, &x) in xs.iter().enumerate() {
        let (px, truth) = r.render(x, k as u64);
        let o = r.optics();
        let f = Frame::new(k as u64, Timestamp::default(), o.width, o.height, px);
        let mut out = vec![LinePeak::NONE; o.height as usize];
        det.detect(&f, &mut out);
        for (p, t) in out.iter().zip(&truth.rows) {
            match t {
                RowTruth::Line { col, .. } => {
                    n += 1;
                    if p.is_valid() {
                        found += 1;
                        sq += (p.col - col).powi(2);
                    }
                }
                RowTruth::NoLine => spurious += p.is_valid() as usize,
            }
        }
    }
    (n, found, (sq / found.max(1) as f64).sqrt(), spurious)
}

#[test]
fn the_red_channel_of_a_colour_camera_is_the_monochrome_frame() {
    let grey = NoiseConfig::default();
    let colour = NoiseConfig {
        colour: Some(ColourCamera {
            channel: Channel::Red,
            ..ColourCamera::red_laser()
        }),
        ..NoiseConfig::default()
    };
    let (a, _) = renderer(grey).render(120.0, 3);
    let (b, _) = renderer(colour).render(120.0, 3);
    assert_eq!(a, b);
    let Pixels::Gray8(_) = a else { panic!("Gray8") };
}

#[test]
fn red_minus_others_separates_a_red_laser_from_room_light() {
    let xs = [60.0, 110.0, 160.0, 210.0];
    // Dark box: the monochrome camera as the scans use it.
    let (n0, f0, rms0, s0) = accuracy(&mut renderer(NoiseConfig::default()), &xs);
    // Warm room light of 60 DN (a third of the laser's peak) on a textured scene (+-60 %):
    // the grey or red image holds the texture's blotches as well as the line.
    let lit = |channel| NoiseConfig {
        ambient_dn: 60.0,
        colour: Some(ColourCamera {
            channel,
            texture: 0.6,
            ..ColourCamera::red_laser()
        }),
        ..NoiseConfig::default()
    };
    let (n1, f1, rms1, s1) = accuracy(&mut renderer(lit(Channel::RedMinusOthers)), &xs);
    let (_, f2, rms2, s2) = accuracy(&mut renderer(lit(Channel::Luma)), &xs);
    let (_, f3, rms3, s3) = accuracy(&mut renderer(lit(Channel::Red)), &xs);
    println!("dark grey: {f0}/{n0} rows, rms {rms0:.4} px, {s0} spurious");
    println!("room light, red-minus-others: {f1}/{n1} rows, rms {rms1:.4} px, {s1} spurious");
    println!("room light, luma: {f2}/{n1} rows, rms {rms2:.4} px, {s2} spurious");
    println!("room light, red: {f3}/{n1} rows, rms {rms3:.4} px, {s3} spurious");
    assert_eq!(n0, n1);
    assert!(f1 * 1000 >= n1 * 995, "{f1}/{n1}");
    // Seen: 0.063 px against 0.045 px in the dark, no spurious row.
    assert!(rms1 < 2.0 * rms0 && rms1 < 0.1, "{rms1} against {rms0}");
    assert_eq!(s1, 0);
    // Seen: luma 818 and red 1195 spurious rows (texture blotches taken for the line where
    // the foot is not), luma 16.6 px RMS.
    assert!(s2 > 100 && s3 > 100, "luma {s2}, red {s3} spurious rows");
    assert!(
        rms2 > 5.0 * rms1 && rms3 > 2.0 * rms1,
        "luma {rms2}, red {rms3}"
    );
}
