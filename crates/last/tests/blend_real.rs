//! The blend fill on the real last pairs: seams measured by the join's seam figures, files
//! read back by independent readers, pictures written.

use footscan_geom::mesh::TriMesh;
use footscan_last::blend::fair::Functional;
use footscan_last::blend::output::{quality, write, Quality};
use footscan_last::blend::weight::Weight;
use footscan_last::blend::{fill, Blend, BlendParams, Piece, Skin};
use footscan_last::join::{reference, study};
use std::path::PathBuf;

fn data_dir() -> PathBuf {
    let d = std::env::var_os("FOOTSCAN_DATA")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data"));
    let lasts = d.join("lasts");
    assert!(
        lasts.is_dir(),
        "real last data missing: {} is not a directory; set FOOTSCAN_DATA to the directory \
         holding lasts/LastScan_Default.stl etc.",
        lasts.display()
    );
    lasts
}

/// The two real pairs as `footscan bench join` takes them: (name, back last, toe last).
fn pairs() -> Vec<(&'static str, TriMesh, TriMesh)> {
    let pairs = study::real_pairs(data_dir().parent().unwrap()).unwrap();
    let names = ["LastScan", "RoundTip"];
    pairs
        .into_iter()
        .zip(names)
        .map(|(p, n)| {
            assert!(p.name.starts_with(n), "{}", p.name);
            (n, p.back, p.toe)
        })
        .collect()
}

fn out_dir() -> PathBuf {
    let d = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("blend_real");
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// One fill's figures.
struct Run {
    pair: &'static str,
    blend: String,
    skin: Skin,
    q: Quality,
    /// The original lasts' facet angles at the back and toe planes, deg (max, mean).
    facets: [(f64, f64); 2],
}

#[test]
fn seams_of_every_blend_on_both_pairs() {
    let blends = [
        (Blend::Fixed(Weight::Morph), Skin::One),
        (Blend::Fixed(Weight::Extension), Skin::One),
        (Blend::Fixed(Weight::Linear), Skin::One),
        (Blend::Fixed(Weight::Poly), Skin::One),
        (Blend::Fair(Functional::Variation), Skin::One),
        (Blend::Fair(Functional::Energy), Skin::One),
        (Blend::Fixed(Weight::Morph), Skin::Pieces),
        (Blend::Fixed(Weight::Poly), Skin::Pieces),
    ];
    println!(
        "{:9} {:18} {:>8} {:>8} {:>15} {:>15} {:>9} {:>9} | {:>13} {:>13} {:>11} {:>11} | {:>10} {:>6} {:>6} {:>5}",
        "pair",
        "blend",
        "gapB mm",
        "gapT mm",
        "nB max/mean",
        "nT max/mean",
        "kB max",
        "kT max",
        "origB deg",
        "origT deg",
        "origB k",
        "origT k",
        "variation",
        "devB",
        "devT",
        "ms"
    );
    let mut runs: Vec<Run> = Vec::new();
    for (pair, back, toe) in pairs() {
        for (b, skin) in &blends {
            let p = BlendParams {
                blend: b.clone(),
                skin: *skin,
                ..Default::default()
            };
            let label = match skin {
                Skin::One => b.name(),
                Skin::Pieces => format!("{} pieces", b.name()),
            };
            let f = fill(&back, &toe, &p).unwrap_or_else(|e| panic!("{pair} {label}: {e}"));
            let q = quality(&f, 400).unwrap();
            let (sb, st, ob, ot) = (&q.back_seam, &q.toe_seam, &q.back_original, &q.toe_original);
            println!(
                "{:9} {:18} {:8.1e} {:8.1e} {:7.1e}/{:7.1e} {:7.1e}/{:7.1e} {:9.1e} {:9.1e} | {:6.2}/{:6.2} {:6.2}/{:6.2} {:5.2}/{:5.2} {:5.2}/{:5.2} | {:10.3e} {:6.3} {:6.3} {:5.1}",
                pair,
                label,
                sb.gap_max_mm,
                st.gap_max_mm,
                sb.normal_max_deg,
                sb.normal_mean_deg,
                st.normal_max_deg,
                st.normal_mean_deg,
                sb.curvature_rel_max,
                st.curvature_rel_max,
                ob.normal_max_deg,
                ob.normal_mean_deg,
                ot.normal_max_deg,
                ot.normal_mean_deg,
                ob.curvature_rel_max,
                ob.curvature_rel_mean,
                ot.curvature_rel_max,
                ot.curvature_rel_mean,
                q.fill_variation,
                q.back_deviation.max_mm,
                q.toe_deviation.max_mm,
                f.timings.total
            );
            if let Some(fr) = &f.fair {
                println!(
                    "          fair table {:?} cost {:.4e} (morph {:.4e}) evals {}",
                    fr.table
                        .iter()
                        .map(|r| (r.1 * 100.0).round() / 100.0)
                        .collect::<Vec<_>>(),
                    fr.cost,
                    fr.cost_morph,
                    fr.evaluations
                );
            }
            write(
                &f,
                &q,
                &out_dir(),
                &format!("{pair}_{}", label.replace(' ', "_")),
            )
            .unwrap();
            let facets = [
                reference::facet_angles(&f.back_mesh, &f.back_plane, 2.5),
                reference::facet_angles(&f.toe_mesh, &f.toe_plane, 2.5),
            ];
            runs.push(Run {
                pair,
                blend: b.name(),
                skin: *skin,
                q,
                facets,
            });
        }
    }
    let get = |pair: &str, blend: &str, skin: Skin| {
        &runs
            .iter()
            .find(|r| r.pair == pair && r.blend == blend && r.skin == skin)
            .unwrap()
            .q
    };
    for r in &runs {
        let who = format!("{} {} {:?}", r.pair, r.blend, r.skin);
        for s in [&r.q.back_seam, &r.q.toe_seam] {
            // Every piece interpolates the same boundary slices at the same parameters.
            assert!(s.gap_max_mm <= 0.01, "{who}: {s:?}");
            if r.skin == Skin::One {
                // One skin: the seams are interior, G1 and G2 to round-off, as the Gordon
                // join's (the same seam code, the same gates).
                assert!(s.normal_max_deg <= 0.1, "{who}: {s:?}");
                assert!(s.curvature_rel_max <= 0.05, "{who}: {s:?}");
            }
        }
        // The kept parts' ends stay on the original lasts' sections (up to the two
        // interpolants of one faceted section between their points).
        for s in [&r.q.back_original, &r.q.toe_original] {
            assert!(s.gap_max_mm <= 0.25, "{who}: {s:?}");
        }
    }
    for pair in ["LastScan", "RoundTip"] {
        let morph = get(pair, "morph", Skin::One);
        let poly = get(pair, "poly", Skin::One);
        let morph_p = get(pair, "morph", Skin::Pieces);
        let poly_p = get(pair, "poly", Skin::Pieces);
        let facets = runs.iter().find(|r| r.pair == pair).unwrap().facets;
        for (m, p, mo, po, floor) in [
            (
                &morph_p.back_seam,
                &poly_p.back_seam,
                &morph.back_original,
                &poly.back_original,
                facets[0],
            ),
            (
                &morph_p.toe_seam,
                &poly_p.toe_seam,
                &morph.toe_original,
                &poly.toe_original,
                facets[1],
            ),
        ] {
            // The morph's slices alone: position-continuous, visibly not tangent-continuous
            // (pieces skinned apart, as the paper shows its figure 2).
            assert!(
                m.normal_max_deg > 10.0 && m.normal_mean_deg > 5.0,
                "{pair}: {m:?}"
            );
            // The polynomial blend's first step is the discrete G1/G2 extension: its slices
            // keep the parts' tangent planes on average to a fraction of the morph's break.
            assert!(
                p.normal_mean_deg < 0.12 * m.normal_mean_deg,
                "{pair}: {p:?}"
            );
            // In one skin the morph's break bends the kept part's end away from its original
            // last; the blend's end stays closer to it, within the angles at which the
            // original's own facets meet there (on average).
            assert!(mo.normal_mean_deg > 2.0, "{pair}: {mo:?}");
            assert!(
                po.normal_mean_deg < 0.6 * mo.normal_mean_deg,
                "{pair}: {po:?}"
            );
            assert!(
                po.normal_mean_deg < floor.1,
                "{pair}: {po:?}, facets {floor:?}"
            );
        }
    }
}

fn venv_python() -> PathBuf {
    let p = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../target/venv-occt/bin/python");
    assert!(
        p.exists(),
        "no OCCT venv at {} (run `bash scripts/setup.sh`)",
        p.display()
    );
    p
}

#[test]
fn written_files_are_read_back_by_independent_readers() {
    let (name, back, toe) = pairs().swap_remove(1);
    let f = fill(&back, &toe, &BlendParams::default()).unwrap();
    let q = quality(&f, 100).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let w = write(&f, &q, dir.path(), name).unwrap();
    let py = venv_python();
    let here = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let run = |script: PathBuf, args: &[&str]| {
        let o = std::process::Command::new(&py)
            .arg(&script)
            .args(args)
            .output()
            .unwrap();
        let s = String::from_utf8_lossy(&o.stdout).to_string();
        assert!(
            o.status.success(),
            "{} rejects {args:?}: {s}{}",
            script.display(),
            String::from_utf8_lossy(&o.stderr)
        );
        s
    };
    let stl = w.stl.to_str().unwrap();
    let s = run(here.join("../../../shared/tools/mesh_check.py"), &[stl]);
    println!("{s}");
    assert!(s.contains(": closed"), "{s}");
    for file in [&w.iges, &w.step] {
        let s = run(
            here.join("../../scripts/occt_readback.py"),
            &[file.to_str().unwrap(), "--unit", "0.3,0.7"],
        );
        let j: serde_json::Value = serde_json::from_str(&s).unwrap();
        assert_eq!(j["valid"], true, "{s}");
        assert_eq!(j["faces"], 3, "{s}");
        // OCCT's surfaces at (0.3, 0.7) of their domains are ours there.
        for (k, surf) in [&f.back, &f.fill, &f.toe].iter().enumerate() {
            let p = &j["surfaces"][k]["points"][0]["p"];
            let theirs = footscan_geom::P3::new(
                p[0].as_f64().unwrap(),
                p[1].as_f64().unwrap(),
                p[2].as_f64().unwrap(),
            );
            let ours = surf.point(0.3, 0.7);
            let dev = (theirs - ours).norm();
            println!("{} surface {k}: OCCT vs ours {dev:.2e} mm", file.display());
            assert!(
                dev < 1e-6,
                "{}: surface {k} differs by {dev} mm",
                file.display()
            );
        }
    }
}

/// The RoundTip pair the other way round (Heeled back, Flat toe, as `footscan bench join`
/// takes it): a blended boundary slice carries a kink that the closed-form extension once
/// amplified to 1e9 mm within five steps. Every fill slice must stay within the two lasts'
/// box.
#[test]
fn fills_stay_between_the_lasts_with_the_heeled_back() {
    let (_, heeled, flat) = pairs().swap_remove(1);
    for w in [Weight::Linear, Weight::Poly] {
        let p = BlendParams {
            blend: Blend::Fixed(w.clone()),
            ..Default::default()
        };
        let f = fill(&heeled, &flat, &p).unwrap();
        let (bb, tb) = (f.back_mesh.bbox(), f.toe_mesh.bbox());
        let (lo, hi) = (bb.min.inf(&tb.min), bb.max.sup(&tb.max));
        let mut worst = 0.0f64;
        for s in f.slices.iter().filter(|s| s.piece == Piece::Fill) {
            for q in &s.points {
                let out = (lo - q).sup(&(q - hi)).max().max(0.0);
                worst = worst.max(out);
            }
        }
        println!("{}: farthest fill point {worst:.3} mm outside the lasts' box, {} points where the closed forms break", w.name(), f.by_curve);
        assert!(worst < 2.0, "{}: {worst} mm outside", w.name());
    }
}

/// Issue 36 item 3: the polynomial blend's fill within twice the Gordon patch's curvature
/// variation (the same integral, `fair::surface_fairness` 96 x 24, the Gordon join at its
/// defaults without the fits). Before R was taken on the quadratic past the first step, b read
/// per slice and the broken points moved with their neighbours, the RoundTip fill was 2.0e6
/// against the patch's 3.7e5 (5.6 times), with stripes every slice in the zebra pictures.
#[test]
fn poly_fill_is_within_twice_the_gordon_patch() {
    use footscan_last::blend::fair::surface_fairness;
    use footscan_last::join::{join, JoinParams};
    for (pair, b, t) in pairs() {
        let f = fill(&b, &t, &BlendParams::default()).unwrap();
        let (fill_var, _) = surface_fairness(&f.fill, 96, 24);
        let j = join(&b, &t, &JoinParams::default()).unwrap();
        let (patch_var, _) = surface_fairness(&j.patch, 96, 24);
        println!(
            "{pair}: poly fill {fill_var:.3e}, Gordon patch {patch_var:.3e} 1/mm^2 ({:.2} times)",
            fill_var / patch_var
        );
        assert!(
            fill_var <= 2.0 * patch_var,
            "{pair}: {fill_var} {patch_var}"
        );
    }
}
