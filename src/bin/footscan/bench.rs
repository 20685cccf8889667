//! `footscan bench ...`: speed and accuracy measurements, printed as a table or JSON.

use anyhow::Result;
use clap::{Parser, Subcommand};
use std::path::PathBuf;

#[path = "bench_customize.rs"]
mod customize;
#[path = "bench_measure.rs"]
mod measure;

#[derive(Parser)]
pub struct Args {
    #[command(subcommand)]
    what: What,
}

#[derive(Subcommand)]
enum What {
    /// Calibration methods side by side: each parameter against the simulator's truth, height
    /// RMS and max error on a held-out staircase and the simulated foot.
    Calibrate {
        #[arg(long, default_value = crate::DEFAULT_CONFIG, help = crate::CONFIG_HELP)]
        config: PathBuf,
        /// Only these methods (repeatable; default insystem, bezier, opencv).
        #[arg(long = "method", value_parser = ["insystem", "bezier", "opencv"])]
        methods: Vec<String>,
        /// Acquire by rendering frames directly (fast) instead of through the real-time
        /// simulated camera and slider.
        #[arg(long)]
        direct: bool,
        /// One JSON array of objects (method, params, val_rms_mm, val_max_mm, ...).
        #[arg(long)]
        json: bool,
    },
    /// Plantar surface models (the plantar scanner paper's Table 1, docs/method.md section
    /// 7.5): the Bezier network against least squares, B-spline approximation, NURBS and C2
    /// B-spline interpolation on one scan, printed beside the paper's figures.
    Surface {
        #[arg(long, default_value = crate::DEFAULT_CONFIG, help = crate::CONFIG_HELP)]
        config: PathBuf,
        /// A saved scan directory (its grid.bin); default: run a simulated scan (~15 s).
        #[arg(long)]
        scan: Option<PathBuf>,
        /// One JSON array of objects instead of the table.
        #[arg(long)]
        json: bool,
    },
    /// Simulator renderer: frames/s on one core for the configured scanner.
    Render {
        #[arg(long, default_value = crate::DEFAULT_CONFIG, help = crate::CONFIG_HELP)]
        config: PathBuf,
        /// Frames to render.
        #[arg(long, default_value_t = 400)]
        frames: u64,
        #[arg(long)]
        json: bool,
    },
    /// Laser-line detectors on real frames of other scanners (MANIFEST.csv in DATA): rows
    /// found where the line is visible, straightness on flat boards, spread on static regions,
    /// false lines on laser-off frames.
    Real {
        /// The frames directory (default: $FOOTSCAN_DATA/frames or ../shared/data/frames).
        #[arg(long)]
        data: Option<PathBuf>,
        /// Only these detectors (repeatable; default all).
        #[arg(long = "detector")]
        detectors: Vec<String>,
        #[arg(long)]
        json: bool,
    },
    /// Laser-line detectors: accuracy against simulator truth over line sigma and noise, and
    /// frames/s per core beside the memory-bandwidth floor (a pass summing every byte).
    Detect {
        /// One JSON array of objects instead of the table.
        #[arg(long)]
        json: bool,
        /// Distinct 1280x1024 frames cycled in the speed test (64 = 84 MB).
        #[arg(long, default_value_t = 64)]
        speed_frames: usize,
        /// Seconds of CPU time per speed measurement.
        #[arg(long, default_value_t = 0.5)]
        seconds: f64,
        /// Only these detectors (repeatable; default all).
        #[arg(long = "detector")]
        detectors: Vec<String>,
        /// Only these line sigmas, px (repeatable; default 0.6 1.0 1.6 2.0 2.5 3.0).
        #[arg(long = "sigma")]
        sigmas: Vec<f64>,
        /// Time only these instruction sets (repeatable: scalar, sse4.1, avx2, avx512;
        /// default every one this CPU runs).
        #[arg(long = "isa")]
        isas: Vec<String>,
        /// Only the speed table: no accuracy sweep.
        #[arg(long)]
        speed_only: bool,
    },
    /// The customized last (docs/method.md section 10) on simulated feet of 230, 260 and 290
    /// mm, both sides, and the real feet of DATA/feet: the rule table, per foot each rule's
    /// foot value, target and value cut from the output last, the minimum clearance, and the
    /// time of the whole customization and of the slowest curve's fit and deformation.
    Customize {
        /// Directory holding feet/ (default: $FOOTSCAN_DATA or ../shared/data).
        #[arg(long)]
        data: Option<PathBuf>,
        /// Only the clinic path's table (scans of simulated feet with their own girths x
        /// the stock lasts of DATA/lasts).
        #[arg(long)]
        clinic_only: bool,
        /// Runs per foot; the fastest is reported.
        #[arg(long, default_value_t = 3)]
        repeats: usize,
        /// One JSON array of objects instead of the tables.
        #[arg(long)]
        json: bool,
    },
    /// Foot measurements (docs/method.md section 8): a population of simulated feet of ten
    /// kinds (flat and high arches, hallux valgus, wide and narrow forefeet, short and long
    /// toes, relaxed, toes joined) against their truth, worst error per kind, and the real
    /// feet of DATA/feet read as they come: heads along the foot, widths, warnings, and one
    /// person's left and right foot against each other.
    Measure {
        /// Directory holding feet/ (default: $FOOTSCAN_DATA or ../shared/data).
        #[arg(long)]
        data: Option<PathBuf>,
        /// Simulated feet (ten kinds in turn).
        #[arg(long, default_value_t = 100)]
        feet: usize,
        /// Seed of the population.
        #[arg(long, default_value_t = 2026)]
        seed: u64,
        /// Height map cell (mm).
        #[arg(long, default_value_t = 0.1)]
        cell_mm: f64,
        /// One JSON object {"population", "real", "pair"} instead of the tables.
        #[arg(long)]
        json: bool,
    },
    /// Last joining on the real last pairs: the Gordon join (45 and 10 deg) beside the blend
    /// fill (linear, poly, fair, the morph alone; the morph and poly also with their pieces
    /// skinned apart) in one table of seam figures, the same seams against the original
    /// lasts, fill fairness, fit of the kept parts and time; then the Gordon join's parameter
    /// study (auxiliary sections, points per section and rotation angle against time and seam
    /// quality).
    Join {
        /// Directory holding lasts/ (default: $FOOTSCAN_DATA or ../shared/data).
        #[arg(long)]
        data: Option<PathBuf>,
        /// Runs per setting; the fastest is reported.
        #[arg(long, default_value_t = 5)]
        repeats: usize,
        /// One JSON object {"methods": [...], "study": [...]} instead of the tables.
        #[arg(long)]
        json: bool,
        /// Also write pictures into this directory: time_vs_points.png (the Gordon join's
        /// time against points per section), zebra_PAIR.png (the Gordon join at 45 deg
        /// beside the polynomial blend, zebra stripes of the join region) and
        /// zebra_morph_PAIR.png (the morph alone, pieces skinned apart, beside the polynomial
        /// blend) for each pair.
        #[arg(long)]
        out: Option<PathBuf>,
    },
}

pub fn run(args: Args) -> Result<()> {
    match args.what {
        What::Calibrate {
            config,
            methods,
            direct,
            json,
        } => {
            use footscan::calib::{CalibrationPlan, Method};
            use footscan_bench::calibrate as bc;
            let cfg = crate::load_config(&config)?;
            let methods: Vec<Method> = if methods.is_empty() {
                Method::ALL.to_vec()
            } else {
                methods
                    .iter()
                    .map(|m| m.parse().map_err(anyhow::Error::msg))
                    .collect::<Result<_>>()?
            };
            let opts = bc::BenchOptions { methods, direct };
            let rows = bc::run(
                &cfg.config,
                &CalibrationPlan::default(),
                &opts,
                &mut |what, done, total| {
                    eprint!("\r{what} {done}/{total}        ");
                },
            )?;
            eprintln!();
            if json {
                println!("{}", serde_json::to_string_pretty(&rows)?);
            } else {
                print!("{}", bc::table(&rows));
            }
            Ok(())
        }
        What::Surface { config, scan, json } => {
            let cfg = crate::load_config(&config)?;
            let grid = footscan_bench::surface::scan_or_load(&cfg, scan.as_deref())
                .map_err(|e| anyhow::anyhow!(e))?;
            let b =
                footscan_bench::surface::run(&cfg.config, &grid).map_err(|e| anyhow::anyhow!(e))?;
            if json {
                println!("{}", serde_json::to_string_pretty(&b.rows)?);
            } else {
                println!("{}", footscan_bench::surface::table(&b));
            }
            Ok(())
        }
        What::Render {
            config,
            frames,
            json,
        } => {
            let cfg = crate::load_config(&config)?;
            let rows =
                footscan_bench::render::run(&cfg.config, frames).map_err(|e| anyhow::anyhow!(e))?;
            if json {
                println!("{}", serde_json::to_string_pretty(&rows)?);
            } else {
                println!("{}", footscan_bench::render::table(&rows));
            }
            Ok(())
        }
        What::Real {
            data,
            detectors,
            json,
        } => {
            use footscan_bench::real;
            let dir = data.unwrap_or_else(real::default_data_dir);
            let detectors = if detectors.is_empty() {
                real::all_detectors()
            } else {
                detectors
            };
            let (rows, spreads) = real::run(&dir, &detectors).map_err(anyhow::Error::msg)?;
            if json {
                println!(
                    "{}",
                    serde_json::to_string_pretty(&serde_json::json!({
                        "regions": rows,
                        "static": spreads,
                        "shares": real::shares(&rows)
                    }))?
                );
            } else {
                print!("{}", real::table(&rows, &spreads));
                print!("{}", real::share_table(&real::shares(&rows)));
            }
            Ok(())
        }
        What::Detect {
            json,
            speed_frames,
            seconds,
            detectors,
            sigmas,
            isas,
            speed_only,
        } => {
            use footscan_bench::detect as bd;
            let mut opts = bd::Options {
                speed_frames,
                seconds,
                ..Default::default()
            };
            for i in &isas {
                let isa: footscan::detect::Isa = i.parse().map_err(anyhow::Error::msg)?;
                if !isa.supported() {
                    anyhow::bail!(
                        "--isa {i}: this CPU does not run it (available: {})",
                        footscan::detect::Isa::available()
                            .iter()
                            .map(|i| i.as_str())
                            .collect::<Vec<_>>()
                            .join(", ")
                    );
                }
                opts.isas.push(isa);
            }
            for d in &detectors {
                footscan::detect::build(d, &Default::default()).map_err(anyhow::Error::msg)?;
            }
            if !detectors.is_empty() {
                opts.detectors = detectors;
            }
            if !sigmas.is_empty() {
                opts.sigmas = sigmas;
            }
            if speed_only {
                let speed = bd::speed_by_isa(&opts);
                if json {
                    println!("{}", serde_json::to_string_pretty(&speed)?);
                } else {
                    print!("{}", bd::speed_table(&speed));
                }
                return Ok(());
            }
            let (rows, speed) = bd::run(&opts);
            if json {
                let all = serde_json::json!({ "accuracy": rows, "speed": speed });
                println!("{}", serde_json::to_string_pretty(&all)?);
            } else {
                print!("{}", bd::table(&rows));
                print!("{}", bd::speed_table(&speed));
            }
            Ok(())
        }
        What::Customize {
            data,
            repeats,
            json,
            clinic_only,
        } => {
            let dir = data_dir(data);
            if !clinic_only {
                customize::run(&dir, repeats, json)?;
            }
            if json && !clinic_only {
                return Ok(());
            }
            customize::run_clinic(&dir, repeats)
        }
        What::Measure {
            data,
            feet,
            seed,
            cell_mm,
            json,
        } => {
            let dir = data_dir(data);
            measure::run(&dir, feet, seed, cell_mm, json)
        }
        What::Join {
            data,
            repeats,
            json,
            out,
        } => {
            use footscan_last::join::{compare, study};
            let dir = data_dir(data);
            let pairs = study::real_pairs(&dir).map_err(|e| {
                anyhow::anyhow!(
                    "{e} (give --data DIR holding lasts/)",
                    e = footscan_util::Chain(&e)
                )
            })?;
            let (rows, pics) = compare::run(&pairs, &compare::methods(), repeats, out.is_some())?;
            let study_rows = study::run(&pairs, &study::paper_cases(), repeats)?;
            if json {
                println!(
                    "{}",
                    serde_json::to_string_pretty(&serde_json::json!({
                        "methods": rows,
                        "study": study_rows
                    }))?
                );
            } else {
                println!(
                    "joining methods on the same lasts and planes (seams: gap, normal jump, \
                     relative curvature jump between the pieces; /orig: the same seam against \
                     the original last there; fill: curvature variation; fit: kept parts \
                     against their meshes, worse of the two; time: best of {repeats})"
                );
                print!("{}", compare::table(&rows));
                println!("\nGordon join parameter study (time: best of {repeats})");
                print!("{}", study::table(&study_rows));
            }
            // Our Gordon surface against OpenCASCADE's on the same network, where the test
            // venv is (scripts/setup.sh makes it).
            let python = std::env::var_os("FOOTSCAN_OCCT_PYTHON")
                .map(PathBuf::from)
                .unwrap_or_else(|| PathBuf::from("target/venv-occt/bin/python"));
            let script = PathBuf::from("scripts/occt_gordon_compare.py");
            if python.exists() && script.exists() {
                println!(
                    "\nour Gordon surface against OpenCASCADE 8's GeomFill_Gordon on the main and \
                     auxiliary sections (time: ours best of 5)"
                );
                for pair in &pairs {
                    match compare::occt_gordon(pair, &python, &script) {
                        Ok(r) => println!(
                            "{}: {} sections x {} guides, ours {:.1} ms, OCCT {:.0} ms, apart {:.1e} \
                             mm at equal parameters, network {:.1e} mm from OCCT's",
                            r.pair,
                            r.sections,
                            r.guides,
                            r.ours_ms,
                            r.occt_ms,
                            r.same_param_max_mm,
                            r.network_to_occt_max_mm
                        ),
                        Err(e) => println!("{}: OCCT comparison failed: {e}", pair.name),
                    }
                }
            } else {
                println!(
                    "\n(no OpenCASCADE comparison: {} or {} missing; run scripts/setup.sh or set \
                     FOOTSCAN_OCCT_PYTHON)",
                    python.display(),
                    script.display()
                );
            }
            if let Some(out) = out {
                std::fs::create_dir_all(&out)?;
                let p = out.join("time_vs_points.png");
                compare::time_vs_points_png(&p, &study_rows)?;
                eprintln!("wrote {}", p.display());
                for pair in &pairs {
                    let p = compare::pair_zebra_png(&out, &pair.name, &pics)?;
                    eprintln!("wrote {}", p.display());
                }
            }
            Ok(())
        }
    }
}

/// The data directory: as given, else $FOOTSCAN_DATA, else ../shared/data.
fn data_dir(data: Option<PathBuf>) -> PathBuf {
    data.unwrap_or_else(|| {
        std::env::var_os("FOOTSCAN_DATA")
            .map(PathBuf::from)
            .unwrap_or_else(|| PathBuf::from("../shared/data"))
    })
}
