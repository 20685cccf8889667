//! `footscan last customize`: a last made for one foot from its characteristic curves and the
//! comfort rules (docs/method.md section 10). The library does the work; this file reads the
//! inputs, prints the rule table and writes the outputs all or nothing.

use anyhow::{anyhow, Result};
use clap::Parser;
use footscan::lastcustom::{load_stock_as, plantar_of_scan};
use footscan_geom::mesh::{Axes, IntakeOptions, Units};
use footscan_last::customize::clinic::{customize_stock_with, StockOptions, TapeGirths};
use footscan_last::customize::rules::{RuleSet, Shoe, Wearer};
use footscan_last::customize::{
    customize, load_foot_with, write_misfit_atomic, write_outputs_atomic, Inputs, HEEL_RANGE_MM,
    MISFIT_FILE,
};
use std::path::PathBuf;
use std::time::Instant;

#[derive(Parser)]
pub struct CustomizeArgs {
    /// The whole foot as a mesh (STL, OBJ or PLY), as a 3D foot scanner or `footscan sim foot`
    /// writes it: read as it comes (unit, up, heel-to-toe, inward triangles and an open top
    /// cut found and mended, each said on the first lines printed; docs/method.md 10.1).
    #[arg(long, required_unless_present = "scan", conflicts_with_all = ["scan", "girths", "stock"])]
    foot: Option<PathBuf>,
    /// Unit of the mesh given (--foot or --stock): mm, cm (a foot), m, or auto (from its
    /// size: a foot is 100-360 mm heel to toe).
    #[arg(long, default_value = "auto")]
    units: Units,
    /// Scale the mesh given (--foot or --stock) to this length (mm; for unscaled model
    /// units): a foot heel to toe, a stock last its longest side; 50-500.
    #[arg(long, value_name = "MM", value_parser = last_length)]
    length: Option<f64>,
    /// Axes of the --foot file: "auto", or heel-to-toe then up, each x, y or z with an
    /// optional sign: "y,z" (heel to toe along +y, z up), "-y,z", "x,y".
    #[arg(
        long,
        default_value = "auto",
        requires = "foot",
        allow_hyphen_values = true
    )]
    axes: Axes,
    /// When the last misses a rule or the foot presses out where the rules say it must fit,
    /// write it anyway, marked (MISFIT.txt, report.json "misfit": true); the exit status is
    /// still non-zero. Without it nothing is written.
    #[arg(long)]
    keep_misfit: bool,
    /// The clinic's way: a plantar scan directory of ours (its measurements.json: length,
    /// widths, side), with --girths and --stock.
    #[arg(long, requires_all = ["girths", "stock"])]
    scan: Option<PathBuf>,
    /// The girths a fitter measured with a tape (TOML, mm): ball, instep, long_heel, ankle.
    #[arg(long)]
    girths: Option<PathBuf>,
    /// A stock last of the foot's side from the shop's collection (closed mesh, z up),
    /// deformed until its cut values meet the rules.
    #[arg(long)]
    stock: Option<PathBuf>,
    /// Refuse a stock last of the other side than the scanned foot (by default it is
    /// mirrored to the foot's side, and the output says so).
    #[arg(long, requires = "stock")]
    strict_sides: bool,
    /// Comfort rule file (TOML by curve type I-IV; see config/last-rules.toml). Default:
    /// $FOOTSCAN_LAST_RULES if set, else the shipped config/last-rules.toml, built into the
    /// binary (so the default does not depend on the working directory).
    #[arg(long)]
    rules: Option<PathBuf>,
    /// Shoe type: dress (leather), sport, football, hiking, casual.
    #[arg(long, default_value = "dress")]
    shoe: Shoe,
    /// Wearer: man, woman, child.
    #[arg(long, default_value = "man")]
    wearer: Wearer,
    /// Heel height of the shoe (mm), 0-120, which rule II-F's ball girth allowance follows.
    /// Default: with --stock the stock last's own (the last keeps its heel), else 25
    #[arg(long, value_parser = heel_mm)]
    heel_mm: Option<f64>,
    /// Output directory (replaced as a whole once everything is written).
    #[arg(long)]
    out: PathBuf,
}

/// A foot or a last is 50-500 mm long (as the other last commands take `--length`).
fn last_length(s: &str) -> Result<f64, String> {
    let l: f64 = s.parse().map_err(|e| format!("{s:?}: {e}"))?;
    if l > 50.0 && l < 500.0 {
        Ok(l)
    } else {
        Err(format!("{l} mm: a foot or a last is 50-500 mm long"))
    }
}

pub fn heel_mm(s: &str) -> Result<f64, String> {
    let h: f64 = s.parse().map_err(|e| format!("{s:?}: {e}"))?;
    if (HEEL_RANGE_MM.0..=HEEL_RANGE_MM.1).contains(&h) {
        Ok(h)
    } else {
        Err(format!(
            "{h} mm: a heel is {:.0}-{:.0} mm high",
            HEEL_RANGE_MM.0, HEEL_RANGE_MM.1
        ))
    }
}

/// The comfort rules (`rules`, else $FOOTSCAN_LAST_RULES, else the shipped ones) and the
/// shoe they are for; read first, so a typo in the rule file is named before any mesh is read.
pub fn rules_and_inputs(
    rules: Option<&std::path::Path>,
    shoe: Shoe,
    wearer: Wearer,
    heel_mm: Option<f64>,
) -> Result<(RuleSet, Inputs)> {
    let path = rules
        .map(PathBuf::from)
        .or_else(|| std::env::var_os("FOOTSCAN_LAST_RULES").map(PathBuf::from));
    let rules = match &path {
        Some(p) => RuleSet::load(p)?,
        None => RuleSet::default_rules(),
    };
    Ok((
        rules,
        Inputs {
            shoe,
            wearer,
            heel_mm,
        },
    ))
}

pub fn run(a: CustomizeArgs) -> Result<()> {
    // The rule file first: a typo in it is named before the foot is read.
    let (rules, inp) = rules_and_inputs(a.rules.as_deref(), a.shoe, a.wearer, a.heel_mm)?;
    let t0 = Instant::now();
    let (c, t_load, t_custom, input) = if let Some(foot_path) = &a.foot {
        let opts = IntakeOptions {
            units: a.units,
            length_mm: a.length,
            axes: a.axes,
        };
        let (foot, frame, intake) =
            load_foot_with(foot_path, &opts).map_err(|e| named(foot_path, e))?;
        for n in &intake.notes {
            println!("{}: {n}", foot_path.display());
        }
        let t_load = t0.elapsed();
        let t1 = Instant::now();
        let c = customize(foot, frame, &rules, &inp).map_err(|e| named(foot_path, e))?;
        (c, t_load, t1.elapsed(), foot_path.clone())
    } else {
        let (scan, girths, stock) = (
            a.scan.as_ref().expect("clap: --foot or --scan"),
            a.girths.as_ref().expect("clap: --scan requires --girths"),
            a.stock.as_ref().expect("clap: --scan requires --stock"),
        );
        let g = TapeGirths::load(girths).map_err(|e| anyhow!(e))?;
        let plantar = plantar_of_scan(scan)?;
        g.check_against(&plantar)
            .map_err(|why| anyhow!("{}: {why}", girths.display()))?;
        let m = load_stock_as(stock, a.units, a.length)?;
        let t_load = t0.elapsed();
        let t1 = Instant::now();
        let name = stock.display().to_string();
        let opts = StockOptions {
            strict_sides: a.strict_sides,
        };
        let c = customize_stock_with(m, &name, &plantar, &g, &rules, &inp, opts)
            .map_err(|e| named(stock, e))?;
        (c, t_load, t1.elapsed(), scan.clone())
    };
    let fm = &c.foot_measures;
    println!(
        "{}: {:?} foot, length {:.2} mm, {} triangles; {:?} last for a {:?}, heel {:.0} mm",
        input.display(),
        c.frame_in_world.side,
        fm.length,
        c.foot.triangles.len(),
        inp.shoe,
        inp.wearer,
        c.heel_mm
    );
    println!(
        "{:5} {:16} {:>8} {:>7} {:>8} {:>8} {:>7} {:>6}  met",
        "rule", "quantity", "foot", "change", "target", "last", "error", "bound"
    );
    for n in &c.notes {
        if n.starts_with("warning: ") {
            println!("{n}");
        } else {
            println!("note: {n}");
        }
    }
    for r in &c.rules {
        if let Some(why) = &r.not_applicable {
            println!(
                "{:5} {:16} {:8.2} {:+7.2} {:8.2} {:>8} {:>7} {:>6}  n/a: {why}",
                r.rule, r.quantity, r.foot_mm, r.change_mm, r.target_mm, "-", "-", "-"
            );
            continue;
        }
        println!(
            "{:5} {:16} {:8.2} {:+7.2} {:8.2} {:8.2} {:+7.3} {:6.2}  {}",
            r.rule,
            r.quantity,
            r.foot_mm,
            r.change_mm,
            r.target_mm,
            r.last_mm,
            r.error_mm,
            r.bound_mm,
            match (r.met, r.built_up_mm != 0.0) {
                (true, false) => "yes".to_string(),
                (true, true) => format!(
                    "yes by the solve; {:+.2} mm from the build-up for the footprint",
                    r.built_up_mm
                ),
                (false, _) => "NO".to_string(),
            }
        );
    }
    println!("(last: measured by cutting the output mesh)");
    for f in &c.fits {
        println!(
            "fit {:16} {:4} points {:4} control points, max {:.4} mm, rms {:.4} mm",
            f.curve, f.data_points, f.control_points, f.max_error_mm, f.rms_error_mm
        );
    }
    for d in &c.curves.deform {
        println!(
            "deform {:16} type {} {:3} nodes, largest control move {:5.2} mm, off the last {:.3} mm, length {:.2} mm{}",
            d.curve,
            d.curve_type,
            d.constraints,
            d.max_control_move_mm,
            d.max_dev_from_last_mm,
            d.length_mm,
            d.target_mm
                .map(|t| format!(" (target {t:.2})"))
                .unwrap_or_default()
        );
    }
    let cl = &c.clearance;
    println!(
        "clearance ({} inside the last, {}, mm): {}; overall {:+.2} at ({:.1}, {:.1}, {:.1}); {}",
        cl.of,
        if cl.of == "footprint" {
            "its plan outline"
        } else {
            "below its top"
        },
        cl.summary(),
        cl.overall_mm,
        cl.worst_at_mm[0],
        cl.worst_at_mm[1],
        cl.worst_at_mm[2],
        if cl.regions.iter().all(|r| r.met()) {
            "fits where the rules say it must"
        } else {
            "does NOT fit where the rules say it must"
        }
    );
    if let Some(why) = &cl.missed_because {
        println!("must-fit missed: {why}");
    }
    // Honest exit: a last that misses its rules is written only when asked, marked, and the
    // status says so either way.
    let misfits = c.misfits();
    let t2 = Instant::now();
    let files = if misfits.is_empty() {
        write_outputs_atomic(&c, &inp, &a.out)?
    } else if a.keep_misfit {
        write_misfit_atomic(&c, &inp, &a.out)?
    } else {
        Vec::new()
    };
    let t_write = t2.elapsed();
    println!(
        "load {:.0} ms, customize {:.0} ms ({} mesh evaluations), write {:.0} ms",
        t_load.as_secs_f64() * 1e3,
        t_custom.as_secs_f64() * 1e3,
        c.evaluations,
        t_write.as_secs_f64() * 1e3
    );
    for f in &files {
        println!("wrote {}", f.display());
    }
    if misfits.is_empty() {
        return Ok(());
    }
    let list = misfits.join("; ");
    if a.keep_misfit {
        Err(anyhow!(
            "{}: the last does not do what its rules ask: {list}; written marked as a misfit ({} in {}, report.json \"misfit\": true)",
            input.display(),
            MISFIT_FILE,
            a.out.display()
        ))
    } else {
        Err(anyhow!(
            "{}: the last does not do what its rules ask: {list}; nothing written (--keep-misfit writes it marked as a misfit)",
            input.display()
        ))
    }
}

/// A customization error with the foot file in front unless the message names it already.
fn named(foot: &std::path::Path, e: footscan_last::customize::CustomizeError) -> anyhow::Error {
    anyhow!(footscan::lastcustom::prefixed(
        foot,
        &footscan_util::chain(&e)
    ))
}
