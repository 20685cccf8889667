//! The footscan command line: a thin shell over the library. One file per command.

mod bench;
mod calibrate;
mod detect;
#[cfg(feature = "fleet")]
mod fleet;
mod insole;
mod last;
mod last_choose;
mod last_customize;
mod last_grade;
mod last_join;
mod measure;
mod model;
mod report;
mod scan;
mod scan_dir;
mod sim;
mod verify;

use anyhow::Result;
use clap::{Parser, Subcommand};
use footscan::scan::{self as fscan, LoadedConfig};
use std::path::{Path, PathBuf};

/// `--config`'s default: a name looked up as `footscan::startup` says.
pub const DEFAULT_CONFIG: &str = "sim.toml";
/// `--config`'s help: where a relative name is looked for.
pub const CONFIG_HELP: &str = "Scanner configuration: a path, or a relative name looked up in \
    the working directory (NAME, config/NAME), $FOOTSCAN_CONFIG_DIR, \
    $XDG_CONFIG_HOME/footscan (~/.config/footscan), /etc/footscan, ../share/footscan beside the \
    executable, and the config/ of the checkout it was built in; first found wins \
    (config/sim.toml: the simulator, config/footscan.toml: hardware)";

/// The scanner config `--config` names (looked up as [`footscan::startup::find_config`] says),
/// loaded; the file used is logged at info level.
pub fn load_config(name: &Path) -> Result<LoadedConfig> {
    let path = footscan::startup::find_config(name)?;
    tracing::info!("scanner config {}", path.display());
    Ok(LoadedConfig::load(&path)?)
}

#[derive(Parser)]
#[command(
    name = "footscan",
    version,
    about = "Laser-line foot scanner and last-design toolkit"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

/// `--side` (`scan`, `sim foot`): which foot, as the command line spells it.
#[derive(Clone, Copy, Debug, clap::ValueEnum)]
pub enum SideArg {
    Left,
    Right,
}

impl From<SideArg> for footscan_geom::Side {
    fn from(s: SideArg) -> Self {
        match s {
            SideArg::Left => Self::Left,
            SideArg::Right => Self::Right,
        }
    }
}

#[derive(Subcommand)]
enum Command {
    /// Run a scan and write points.ply, heightmap.png, scan.json and calibration.toml to --out.
    /// The scan is written beside --out and moved there when it ends; an earlier scan in
    /// --out is kept whole as --out.previous-<UTC time>.
    Scan {
        #[arg(long, default_value = crate::DEFAULT_CONFIG, help = crate::CONFIG_HELP)]
        config: PathBuf,
        /// Scan folder: new, empty, or holding an earlier scan (kept, renamed).
        #[arg(long)]
        out: PathBuf,
        /// Calibration TOML (default for the simulator: its true model).
        #[arg(long)]
        calibration: Option<PathBuf>,
        /// No progress bar.
        #[arg(long)]
        quiet: bool,
        /// The foot on the glass, "left" or "right": checked against the scan (hallux and
        /// first metatarsal on the medial side); a mismatch fails the command.
        #[arg(long)]
        side: Option<SideArg>,
    },
    /// Write the simulated scanner's true calibration as a calibration TOML.
    SimCalibration {
        #[arg(long, default_value = crate::DEFAULT_CONFIG, help = crate::CONFIG_HELP)]
        config: PathBuf,
        #[arg(long)]
        out: PathBuf,
    },
    /// List the pipeline stages a config may name; with --config, also load and check the
    /// plugin stages (wasm, exec) that config names and say where each sits.
    Stages {
        #[arg(long)]
        config: Option<PathBuf>,
    },
    /// Build the Bezier-network plantar model of a saved scan and write it as closed meshes.
    Model(model::Args),
    /// An orthotic insole from a saved plantar scan: STL, 3MF, STEP, pictures, insole.json.
    Insole(insole::Args),
    /// Foot measurements of a saved scan: measurements.json and plantar.png, in the scan
    /// directory or only in --out.
    Measure(measure::Args),
    /// Calibrate the scanner (insystem, bezier or the OpenCV reference) into a calibration TOML.
    Calibrate(calibrate::Args),
    /// The daily check: the staircase gauge measured with the current calibration, pass/fail.
    Verify(verify::Args),
    /// The printable PDF report of a measured scan: the foot at 1:1, a 100 mm calibration bar.
    Report(report::Args),
    /// Measure speed and accuracy (see `footscan bench --help`).
    Bench(bench::Args),
    /// Run a laser-line detector on recorded frames and write one CSV line per image row.
    Detect(detect::Args),
    /// Shoe-last stages on meshes (see `footscan last --help`).
    Last(last::Args),
    /// The simulator's objects as files with their truth (see `footscan sim --help`).
    Sim(sim::Args),
    /// The fleet database the daemons push scans to: migrate, list, show, fetch.
    #[cfg(feature = "fleet")]
    Fleet(fleet::Args),
}

fn main() -> std::process::ExitCode {
    // Output piped into `head` and closed early ends the program quietly, as for any Unix
    // tool, instead of a panic on the next print.
    // SAFETY: restoring a signal's default disposition before any thread exists.
    unsafe { libc::signal(libc::SIGPIPE, libc::SIG_DFL) };
    match run() {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            // The chain, each cause once: library errors name what failed and leave the cause
            // to their source.
            eprintln!("error: {e:#}");
            std::process::ExitCode::FAILURE
        }
    }
}

fn run() -> Result<()> {
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env().unwrap_or_else(|_| "warn".into()),
        )
        .with_writer(std::io::stderr)
        .with_ansi(footscan::startup::log_colour())
        .init();
    match Cli::parse().command {
        Command::Scan {
            config,
            out,
            calibration,
            quiet,
            side,
        } => scan::run(config, out, calibration, quiet, side),
        Command::SimCalibration { config, out } => {
            let cfg = load_config(&config)?;
            fscan::sim::true_calibration(&cfg.config).save(&out)?;
            println!("wrote {}", out.display());
            Ok(())
        }
        Command::Stages { config } => {
            for (name, desc) in fscan::registry().entries() {
                println!("{name:16} {desc}");
            }
            match config {
                Some(path) => plugin_stages(&path),
                None => Ok(()),
            }
        }
        Command::Model(args) => model::run(args),
        Command::Insole(args) => insole::run(args),
        Command::Measure(args) => measure::run(args),
        Command::Calibrate(args) => calibrate::run(args),
        Command::Verify(args) => verify::run(args),
        Command::Report(args) => report::run(args),
        Command::Bench(args) => bench::run(args),
        Command::Detect(args) => detect::run(args),
        Command::Last(args) => last::run(args),
        Command::Sim(args) => sim::run(args),
        #[cfg(feature = "fleet")]
        Command::Fleet(args) => fleet::run(args),
    }
}

/// Without the `plugins` feature no `wasm` or `exec` stage can run: a config naming one fails
/// the listing.
#[cfg(not(feature = "plugins"))]
fn plugin_stages(path: &Path) -> Result<()> {
    let cfg = load_config(path)?;
    if let Some((i, s)) = cfg
        .config
        .pipeline
        .stages
        .iter()
        .enumerate()
        .find(|(_, s)| matches!(s.stage.as_str(), "wasm" | "exec"))
    {
        anyhow::bail!(
            "{}: pipeline.stages[{i}] is a `{}` stage, and this footscan was built without the \
             `plugins` feature: build it with default features (`cargo build --release`)",
            path.display(),
            s.stage
        );
    }
    println!("\nplugin stages of {}:\n(none)", path.display());
    Ok(())
}

/// The plugin stages of the pipeline in `path`, each loaded and checked as a scan would: a
/// module that does not load or a command that does not start fails the listing.
#[cfg(feature = "plugins")]
fn plugin_stages(path: &Path) -> Result<()> {
    use anyhow::Context;
    let text =
        std::fs::read_to_string(path).with_context(|| format!("reading {}", path.display()))?;
    let spec = footscan::pipeline::PipelineSpec::from_toml_str(&text)
        .with_context(|| format!("{}: [pipeline]", path.display()))?;
    println!("\nplugin stages of {}:", path.display());
    let mut n = 0;
    for (i, s) in spec.stages.iter().enumerate() {
        let at = format!("pipeline.stages[{i}]");
        match s.stage.as_str() {
            "wasm" => {
                let module = s
                    .params
                    .get("module")
                    .and_then(toml::Value::as_str)
                    .with_context(|| format!("{at}: `module` (a .wasm file) is required"))?;
                let p = footscan_plugins::wasm::WasmPlugin::load(Path::new(module))
                    .with_context(|| at.clone())?;
                if p.wants_files() && s.params.get("grant").is_none() {
                    anyhow::bail!(
                        "{at}: plugin {module}: imports the file system (WASI), but the stage \
                         grants it no directory (grant = \"DIR\" or \"scan\"; docs/plugins.md)"
                    );
                }
                println!("{at:20} wasm {module}: {}", p.kind().place());
            }
            "exec" => {
                let cmd: Vec<String> = s
                    .params
                    .get("command")
                    .and_then(toml::Value::as_array)
                    .map(|a| {
                        a.iter()
                            .filter_map(|v| v.as_str().map(str::to_owned))
                            .collect()
                    })
                    .with_context(|| format!("{at}: `command` (a list of strings) is required"))?;
                use footscan_plugins::exec::ExecRole;
                let (role, place) = match s.params.get("place").and_then(toml::Value::as_str) {
                    None | Some("frame") => (
                        ExecRole::Detector,
                        "per frame (detector: frame rows in, line per row out)",
                    ),
                    Some("scan") => (ExecRole::Scan, "per scan (the point set in, values out)"),
                    Some("sink") => (
                        ExecRole::Sink,
                        "sink (the scan summary and directory in, a report out)",
                    ),
                    Some(other) => anyhow::bail!(
                        "{at}: place = {other:?}: valid places are \"frame\", \"scan\" and \"sink\""
                    ),
                };
                // Started and stopped: the hello/ready exchange is the check.
                footscan_plugins::exec::ExecDetector::start_as(
                    role,
                    &cmd,
                    &[],
                    footscan_plugins::exec::ExecLimits::default(),
                )
                .with_context(|| at.clone())?;
                println!("{at:20} exec {}: {place}", cmd.join(" "));
            }
            _ => continue,
        }
        n += 1;
    }
    if n == 0 {
        println!("(none)");
    }
    Ok(())
}
