use super::*;
use crate::foot::{Foot, FootParams};

fn renderer(optics: Optics, noise: NoiseConfig, scene: Scene) -> Renderer {
    Renderer::new(optics, noise, scene, 42).unwrap()
}

fn lines(t: &FrameTruth) -> impl Iterator<Item = (usize, f64, [f64; 3])> + '_ {
    t.rows.iter().enumerate().filter_map(|(r, rt)| match rt {
        RowTruth::Line { col, point } => Some((r, *col, *point)),
        RowTruth::NoLine => None,
    })
}

#[test]
fn ideal_model_truth_is_the_closed_form() {
    let o = Optics::default().ideal();
    for h in [0.0, 12.5, 40.0] {
        let r = renderer(
            o.clone(),
            NoiseConfig::default(),
            Scene::Plate { height_mm: h },
        );
        let t = r.truth(123.0);
        assert_eq!(
            t.line_count(),
            o.height as usize,
            "every row sees the plate"
        );
        let col = o.cx + o.f_px * o.l_mm / (o.d_mm + h);
        for (row, c, p) in lines(&t) {
            assert!((c - col).abs() < 1e-6, "h {h} row {row}: {c} vs {col}");
            let y = (row as f64 - o.cy) * (o.d_mm + h) / o.f_px;
            assert!((p[1] - y).abs() < 1e-6 && (p[2] - h).abs() < 1e-12);
            assert!((p[0] - 123.0 - o.l_mm).abs() < 1e-12);
        }
    }
}

#[test]
fn general_model_truth_is_consistent() {
    let o = Optics::default();
    let foot = Foot::new(FootParams::default()).unwrap();
    let proj = o.projector();
    let mut checked = 0;
    for scene in [Scene::Plate { height_mm: 7.0 }, Scene::Foot(foot.clone())] {
        let r = renderer(o.clone(), NoiseConfig::default(), scene.clone());
        for x in [40.0, 75.0, 120.0, 180.0, 250.0, 280.0] {
            let t = r.truth(x);
            for (row, c, p) in lines(&t) {
                let img = proj.project(x, p).unwrap();
                assert!((img[0] - c).abs() < 1e-6, "col {} vs {c}", img[0]);
                assert!(
                    (img[1] - row as f64).abs() < 1e-6,
                    "row {} vs {row}",
                    img[1]
                );
                assert!((p[0] - proj.laser_x(x, p[1], p[2])).abs() < 1e-9);
                let h = match &scene {
                    Scene::Foot(f) => f.height(p[0], p[1]).unwrap(),
                    _ => 7.0,
                };
                assert!((p[2] - h).abs() < 1e-9, "off surface by {}", p[2] - h);
                checked += 1;
            }
        }
    }
    assert!(checked > 6000, "checked {checked}");
}

#[test]
fn foot_truth_appears_only_where_the_plane_meets_the_foot() {
    let foot = Foot::new(FootParams::default()).unwrap();
    let r = renderer(Optics::default(), NoiseConfig::default(), Scene::Foot(foot));
    // Laser at world x = X + 70: the foot spans about 110..360.
    assert_eq!(r.truth(20.0).line_count(), 0);
    assert_eq!(r.truth(300.0).line_count(), 0);
    let mid = r.truth(130.0);
    // ~58 mm of foot at x' = 0.36 L, ~8 rows/mm.
    assert!(
        mid.line_count() > 350 && mid.line_count() < 750,
        "{}",
        mid.line_count()
    );
    // Contact rows are at the glass column.
    let glass = r.glass_columns();
    let on_glass = lines(&mid)
        .filter(|(row, c, _)| (c - glass[*row].unwrap()).abs() < 1e-9)
        .count();
    assert!(on_glass > 100, "{on_glass}");
    // Toes: several separate stretches.
    let toes = r.truth(345.0 - 70.0);
    let mut runs = 0;
    let mut prev = false;
    for rt in &toes.rows {
        let on = matches!(rt, RowTruth::Line { .. });
        if on && !prev {
            runs += 1;
        }
        prev = on;
    }
    assert!(runs >= 3, "toe runs {runs}");
}

fn frame(r: &mut Renderer, x: f64, k: u64) -> (Pixels, FrameTruth) {
    r.render(x, k)
}

#[test]
fn render_into_reuses_the_buffers() {
    let foot = Foot::new(FootParams::default()).unwrap();
    let mut r = renderer(Optics::default(), NoiseConfig::default(), Scene::Foot(foot));
    let mut px = Pixels::Gray8(Vec::new());
    let mut t = FrameTruth::default();
    r.render_into(100.0, 0, &mut px, &mut t);
    let ptrs = |px: &Pixels, t: &FrameTruth| match px {
        Pixels::Gray8(v) => (v.as_ptr() as usize, t.rows.as_ptr() as usize),
        Pixels::Gray16(_) => unreachable!(),
    };
    let before = ptrs(&px, &t);
    for k in 1..4 {
        r.render_into(100.0 + k as f64, k, &mut px, &mut t);
        assert_eq!(ptrs(&px, &t), before);
    }
    assert_eq!(px.len(), 1280 * 1024);
    assert_eq!(t.rows.len(), 1024);
}

fn centroid(row: &[f64], col: f64, amb: f64, reach: f64) -> f64 {
    let (mut s, mut sw) = (0.0, 0.0);
    let c0 = (col - reach).floor().max(0.0) as usize;
    let c1 = ((col + reach).ceil() as usize).min(row.len() - 1);
    for (c, v) in row.iter().enumerate().take(c1 + 1).skip(c0) {
        let w = v - amb;
        s += w * c as f64;
        sw += w;
    }
    s / sw
}

#[test]
fn noise_free_line_centroid_matches_truth() {
    let foot = Foot::new(FootParams::default()).unwrap();
    for format in [PixelFormat::Gray8, PixelFormat::Gray16] {
        let noise = NoiseConfig {
            format,
            ..NoiseConfig::noise_free()
        };
        let mut r = renderer(Optics::default(), noise, Scene::Foot(foot.clone()));
        let mut px = Pixels::Gray8(Vec::new());
        let mut t = FrameTruth::default();
        r.render_into(140.0, 0, &mut px, &mut t);
        assert_eq!(px.format(), format);
        let w = 1280;
        let vals: Vec<f64> = match &px {
            Pixels::Gray8(v) => v.iter().map(|&x| x as f64).collect(),
            Pixels::Gray16(v) => v.iter().map(|&x| x as f64 / 257.0).collect(),
        };
        let (mut worst, mut sum, mut n) = (0.0f64, 0.0, 0);
        for (row, c, _) in lines(&t) {
            let e = centroid(&vals[row * w..(row + 1) * w], c, 8.0, 8.0) - c;
            worst = worst.max(e.abs());
            sum += e * e;
            n += 1;
        }
        let rms = (sum / n as f64).sqrt();
        println!("{format:?}: {n} rows, centroid error rms {rms:.5} max {worst:.5}");
        assert!(n > 400);
        let (rms_max, worst_max) = match format {
            PixelFormat::Gray8 => (0.01, 0.03),
            PixelFormat::Gray16 => (0.001, 0.003),
        };
        assert!(
            rms < rms_max && worst < worst_max,
            "{format:?} rms {rms} max {worst}"
        );
        // Background is exactly the ambient level.
        assert_eq!(vals[5], 8.0);
    }
}

#[test]
fn frames_are_deterministic_per_index() {
    let mut r = renderer(
        Optics::default(),
        NoiseConfig::default(),
        Scene::Plate { height_mm: 3.0 },
    );
    let (a, ta) = frame(&mut r, 100.0, 7);
    let (_, _) = frame(&mut r, 50.0, 3);
    let (b, tb) = frame(&mut r, 100.0, 7);
    assert_eq!(a, b);
    assert_eq!(ta, tb);
    let mut r2 = renderer(
        Optics::default(),
        NoiseConfig::default(),
        Scene::Plate { height_mm: 3.0 },
    );
    let (c, _) = frame(&mut r2, 100.0, 7);
    assert_eq!(
        a, c,
        "a new renderer with the same seed gives the same frame"
    );
    let (d, _) = frame(&mut r, 100.0, 8);
    assert_ne!(a, d, "another index gives other noise");
    let mut r3 = Renderer::new(
        Optics::default(),
        NoiseConfig::default(),
        Scene::Plate { height_mm: 3.0 },
        43,
    )
    .unwrap();
    let (e, _) = frame(&mut r3, 100.0, 7);
    assert_ne!(a, e, "another seed gives other noise");
}

#[test]
fn background_noise_statistics() {
    let mut r = renderer(Optics::default(), NoiseConfig::default(), Scene::Empty);
    let (px, t) = frame(&mut r, 0.0, 1);
    assert_eq!(t.line_count(), 0);
    let Pixels::Gray8(v) = px else { panic!() };
    let n = v.len() as f64;
    let mean = v.iter().map(|&x| x as f64).sum::<f64>() / n;
    let var = v.iter().map(|&x| (x as f64 - mean).powi(2)).sum::<f64>() / n;
    // ambient 8, read 2, shot sqrt(8/40): sd = sqrt(4.2 + 1/12 rounding).
    assert!((mean - 8.0).abs() < 0.02, "mean {mean}");
    assert!(
        (var.sqrt() - (4.2f64 + 1.0 / 12.0).sqrt()).abs() < 0.03,
        "sd {}",
        var.sqrt()
    );
}

#[test]
fn noisy_line_is_near_truth_and_speckled() {
    let mut r = renderer(
        Optics::default(),
        NoiseConfig::default(),
        Scene::Plate { height_mm: 10.0 },
    );
    let (px, t) = frame(&mut r, 0.0, 5);
    let Pixels::Gray8(v) = px else { panic!() };
    let vals: Vec<f64> = v.iter().map(|&x| x as f64).collect();
    let errs: Vec<f64> = lines(&t)
        .map(|(row, c, _)| centroid(&vals[row * 1280..(row + 1) * 1280], c, 8.0, 6.0) - c)
        .collect();
    let rms = (errs.iter().map(|e| e * e).sum::<f64>() / errs.len() as f64).sqrt();
    // Speckle dominates: ~0.1-0.2 px per row, far from noise-free and far from lost.
    assert!(rms > 0.03 && rms < 0.4, "rms {rms}");
}

#[test]
fn glass_reflection_and_spikes() {
    let noise = NoiseConfig {
        glass_reflection: 0.3,
        specular_spike_rate: 20.0,
        ..NoiseConfig::noise_free()
    };
    let mut r = renderer(Optics::default(), noise, Scene::Plate { height_mm: 20.0 });
    let (px, t) = frame(&mut r, 0.0, 0);
    let Pixels::Gray8(v) = px else { panic!() };
    let row = 500;
    let g = r.glass_columns()[row].unwrap().round() as usize;
    let RowTruth::Line { col, .. } = t.rows[row] else {
        panic!()
    };
    let l = col.round() as usize;
    assert!(g - l > 30, "glass line separate from the plate line");
    let (pg, pl) = (v[row * 1280 + g] as f64, v[row * 1280 + l] as f64);
    assert!(
        (pg - 8.0) / (pl - 8.0) > 0.2 && (pg - 8.0) / (pl - 8.0) < 0.4,
        "{pg} {pl}"
    );
    let saturated = v.iter().filter(|&&x| x == 255).count();
    assert!(saturated >= 5 * 5, "spikes: {saturated} saturated pixels");
    // Empty scene: glass reflection only, truth says no line.
    let noise = NoiseConfig {
        glass_reflection: 0.3,
        ..NoiseConfig::noise_free()
    };
    let mut r = renderer(Optics::default(), noise, Scene::Empty);
    let (px, t) = frame(&mut r, 0.0, 0);
    assert_eq!(t.line_count(), 0);
    let Pixels::Gray8(v) = px else { panic!() };
    assert!(v[row * 1280 + g] > 50);
}

#[test]
fn gain_scales_the_signal() {
    let mut r = renderer(
        Optics::default(),
        NoiseConfig::noise_free(),
        Scene::Plate { height_mm: 0.0 },
    );
    let (a, t) = frame(&mut r, 0.0, 0);
    r.set_gain(0.5).unwrap();
    let (b, _) = frame(&mut r, 0.0, 0);
    let (Pixels::Gray8(a), Pixels::Gray8(b)) = (a, b) else {
        panic!()
    };
    let RowTruth::Line { col, .. } = t.rows[300] else {
        panic!()
    };
    let i = 300 * 1280 + col.round() as usize;
    assert!(
        ((b[i] as f64) - (a[i] as f64) / 2.0).abs() <= 1.0,
        "{} {}",
        a[i],
        b[i]
    );
    assert!(r.set_gain(-1.0).is_err());
}

#[test]
fn config_is_validated() {
    let n = NoiseConfig {
        drop_rate: 1.5,
        ..NoiseConfig::default()
    };
    let e = Renderer::new(Optics::default(), n, Scene::Empty, 0)
        .unwrap_err()
        .to_string();
    assert!(e.contains("drop_rate") && e.contains("[0, 1]"), "{e}");
    let n: NoiseConfig = toml::from_str("format = \"gray16\"\nenabled = false").unwrap();
    assert_eq!(n.format, PixelFormat::Gray16);
    assert!(toml::from_str::<NoiseConfig>("sigma = 1").is_err());
}

#[test]
fn inverse_normal_is_accurate() {
    for p in [1e-6, 0.01, 0.3, 0.5, 0.9, 0.999] {
        let x = inverse_normal_cdf(p);
        let back = 0.5 * libm::erfc(-x / std::f64::consts::SQRT_2);
        assert!((back - p).abs() < 1e-12 * p.max(1e-3), "{p}");
    }
}

#[test]
fn laser_off_frames_have_no_line_and_the_same_background() {
    let noise = NoiseConfig {
        glass_reflection: 0.3,
        specular_spike_rate: 5.0,
        ..NoiseConfig::default()
    };
    let mut r = renderer(Optics::default(), noise, Scene::Plate { height_mm: 10.0 });
    let (mut on, mut off) = (Pixels::Gray8(Vec::new()), Pixels::Gray8(Vec::new()));
    let (mut t_on, mut t_off) = (FrameTruth::default(), FrameTruth::default());
    r.render_into_lit(50.0, 7, true, &mut on, &mut t_on);
    r.render_into_lit(50.0, 7, false, &mut off, &mut t_off);
    assert!(t_on.line_count() > 0);
    assert_eq!(t_off.line_count(), 0, "no line while the laser is off");
    assert_eq!(t_off.slider_x, t_on.slider_x);
    let (Pixels::Gray8(a), Pixels::Gray8(b)) = (&on, &off) else {
        unreachable!()
    };
    // Same background noise (same frame index): only pixels near the line differ.
    let differ = a.iter().zip(b).filter(|(x, y)| x != y).count();
    assert!(
        differ * 20 < a.len(),
        "{differ} of {} pixels differ",
        a.len()
    );
    let brightest = |v: &[u8]| *v.iter().max().unwrap();
    assert!(
        brightest(a) > 150 && brightest(b) < 60,
        "{} {}",
        brightest(a),
        brightest(b)
    );
}
