//! `footscan last choose`: the shop's lasts ranked by how little each must change to fit a
//! scanned foot (docs/method.md 9.5), the best one customized by the clinic path.

use anyhow::{anyhow, bail, Result};
use clap::Parser;
use footscan::lastcustom::{plantar_of_scan, STOCK_EXTENSIONS};
use footscan_geom::mesh::Units;
use footscan_last::choose::{foot_targets, judge_files, mirrored, rank, Wanted};
use footscan_last::customize::clinic::{customize_stock, TapeGirths};
use footscan_last::customize::rules::{Shoe, Wearer};
use footscan_last::customize::write_outputs_atomic;
use std::path::PathBuf;
use std::time::Instant;

#[derive(Parser)]
pub struct ChooseArgs {
    /// The plantar scan directory (its measurements.json: length, widths, side).
    #[arg(long)]
    scan: PathBuf,
    /// The girths a fitter measured with a tape (TOML, mm): ball, instep, long_heel, ankle.
    #[arg(long)]
    girths: PathBuf,
    /// The shop's collection: every STL, OBJ and PLY file in this directory is a last.
    #[arg(long)]
    stock_dir: PathBuf,
    /// Units of the last files: mm, m, or auto (decided from the size). A file listed in the
    /// collection's lasts.toml is read as that says.
    #[arg(long, default_value = "auto")]
    units: Units,
    /// Scale every last so its longest side is this many mm (a collection of model-unit
    /// files). A collection mixing units gives each model-unit file's length in a lasts.toml
    /// beside them instead (`["NAME.stl"] length_mm = 265`).
    #[arg(long)]
    length: Option<f64>,
    /// Comfort rule file (default: $FOOTSCAN_LAST_RULES, else the shipped rules).
    #[arg(long)]
    rules: Option<PathBuf>,
    #[arg(long, default_value = "dress")]
    shoe: Shoe,
    #[arg(long, default_value = "man")]
    wearer: Wearer,
    /// Heel height of the shoe (mm), 0-120, for every last. Default: each last's own (a
    /// stock last keeps its heel; rule II-F's ball girth allowance follows it)
    #[arg(long, value_parser = crate::last_customize::heel_mm)]
    heel_mm: Option<f64>,
    /// Print the ranking as JSON.
    #[arg(long)]
    json: bool,
    /// Customize the best last that succeeds into this directory (all or nothing).
    #[arg(long)]
    out: Option<PathBuf>,
}

pub fn run(a: ChooseArgs) -> Result<()> {
    let (rules, inp) =
        crate::last_customize::rules_and_inputs(a.rules.as_deref(), a.shoe, a.wearer, a.heel_mm)?;
    let g = TapeGirths::load(&a.girths).map_err(|e| anyhow!(e))?;
    let plantar = plantar_of_scan(&a.scan)?;
    let mut files: Vec<PathBuf> = std::fs::read_dir(&a.stock_dir)
        .map_err(|e| {
            anyhow!(
                "{}: {e}",
                a.stock_dir.display(),
                e = footscan_util::Chain(&e)
            )
        })?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| {
            p.extension()
                .and_then(|x| x.to_str())
                .is_some_and(|x| STOCK_EXTENSIONS.contains(&x.to_ascii_lowercase().as_str()))
        })
        .collect();
    files.sort();
    if files.is_empty() {
        bail!(
            "{}: no lasts (STL, OBJ or PLY meshes, or XYZ point clouds) in the collection",
            a.stock_dir.display()
        );
    }
    // The collection's own file, checked before any last is read.
    footscan_last::collection::Collection::load(&a.stock_dir).map_err(|e| anyhow!(e))?;
    let rows = foot_targets(&plantar, &g, &rules, &inp);
    let t0 = Instant::now();
    let want = Wanted {
        girths: &g,
        rules: &rules,
        inp: &inp,
    };
    let judged = judge_files(&files, a.units, a.length, &plantar, &want);
    let mut cands: Vec<_> = judged.iter().map(|(c, _)| c.clone()).collect();
    rank(&mut cands);
    let rank_ms = t0.elapsed().as_secs_f64() * 1e3;
    if a.json {
        println!("{}", serde_json::to_string_pretty(&cands)?);
    } else {
        println!(
            "{:?} foot {:.1} mm ({}); targets: {}{}",
            plantar.side,
            plantar.length,
            a.scan.display(),
            rows.iter()
                .map(|r| format!("{} {} {:.1}", r.rule, r.quantity, r.target_mm))
                .collect::<Vec<_>>()
                .join(", "),
            if inp.heel_mm.is_none() {
                format!(
                    " (ball girth at a {:.0} mm heel: each last's own heel moves it, as its \
                     note says)",
                    inp.heel()
                )
            } else {
                String::new()
            }
        );
        println!("rank  largest change (mm)      outline (mm)  last");
        for (k, c) in cands.iter().enumerate() {
            println!(
                "{:4}  {:7.2} {:16} {:8.2}      {}{}",
                k + 1,
                c.largest_change_mm,
                c.largest_at,
                c.outline_change_mm,
                c.name,
                if c.mirrored { " (mirrored)" } else { "" }
            );
            for n in &c.notes {
                println!("        note: {n}");
            }
            for n in &c.cannot {
                println!("        cannot: {n}");
            }
        }
        println!("ranked {} lasts in {rank_ms:.0} ms", cands.len());
    }
    let Some(out) = &a.out else {
        return Ok(());
    };
    for c in cands.iter().filter(|c| c.eligible) {
        let Some((_, Some(mesh))) = judged.iter().find(|(j, _)| j.name == c.name) else {
            continue;
        };
        let mesh = if c.mirrored {
            mirrored(mesh.clone())
        } else {
            mesh.clone()
        };
        let t1 = Instant::now();
        let r = customize_stock(mesh, &c.name, &plantar, &g, &rules, &inp)
            .map_err(|e| anyhow!(e))
            .and_then(|done| write_outputs_atomic(&done, &inp, out).map_err(|e| anyhow!(e)));
        match r {
            Ok(files) => {
                eprintln!(
                    "customized {}{} in {:.0} ms",
                    c.name,
                    if c.mirrored { " (mirrored)" } else { "" },
                    t1.elapsed().as_secs_f64() * 1e3
                );
                for f in files {
                    eprintln!("wrote {}", f.display());
                }
                return Ok(());
            }
            Err(e) => eprintln!("customizing {} failed: {e:#}; trying the next", c.name),
        }
    }
    bail!(
        "no last of {} could be customized for this foot",
        a.stock_dir.display()
    )
}
