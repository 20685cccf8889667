//! What the two programs (`footscan`, `footscand`) settle before any work: which config file a
//! relative `--config` name means, and whether the log may colour its lines.
//!
//! A relative config path is looked up, first found wins, in
//!
//! 1. the working directory (`NAME`, then `config/NAME`: a checkout's layout),
//! 2. `$FOOTSCAN_CONFIG_DIR/NAME`,
//! 3. `$XDG_CONFIG_HOME/footscan/NAME` (`~/.config/footscan/NAME` when unset),
//! 4. `/etc/footscan/NAME`,
//! 5. `<dir of the executable>/../share/footscan/NAME` (an installed tree: `bin/`, `share/`),
//! 6. the checkout the executable was built in (`<checkout>/config/NAME`, when the executable
//!    lies under a directory holding `Cargo.toml` and `config/`, as `target/debug/footscan`).
//!
//! An absolute path is taken as it is. When no place has the file, the error lists every
//! place looked at, in this order.

use std::fmt;
use std::path::{Path, PathBuf};

/// The environment variable naming a directory of config files (place 2).
pub const CONFIG_DIR_ENV: &str = "FOOTSCAN_CONFIG_DIR";
/// The system config directory (place 4).
pub const SYSTEM_CONFIG_DIR: &str = "/etc/footscan";

/// One place a config file was looked for.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Place {
    /// The file that would have been used; `None` when the place is not defined (an
    /// environment variable unset, no checkout around the executable).
    pub path: Option<PathBuf>,
    /// What the place is, in words.
    pub what: String,
}

/// No place held the config file.
#[derive(Debug)]
pub struct ConfigNotFound {
    pub name: PathBuf,
    pub places: Vec<Place>,
}

impl fmt::Display for ConfigNotFound {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "config file {} not found; looked in, in order:",
            self.name.display()
        )?;
        for p in &self.places {
            match &p.path {
                Some(path) => write!(f, "\n  {} ({})", path.display(), p.what)?,
                None => write!(f, "\n  - ({})", p.what)?,
            }
        }
        write!(
            f,
            "\npass --config with an existing file, or put {} in one of these places",
            self.name.display()
        )
    }
}

impl std::error::Error for ConfigNotFound {}

/// Where the places of the module doc are on this machine, for `name`, from the given
/// environment (`env` reads a variable; `exe` is the running executable's path).
pub fn places_with(
    name: &Path,
    cwd: &Path,
    env: impl Fn(&str) -> Option<String>,
    exe: Option<&Path>,
) -> Vec<Place> {
    let set = |k: &str| env(k).filter(|v| !v.is_empty());
    let mut places = vec![Place {
        path: Some(cwd.join(name)),
        what: "working directory".into(),
    }];
    places.push(Place {
        path: Some(cwd.join("config").join(name)),
        what: "config/ of the working directory".into(),
    });
    places.push(Place {
        path: set(CONFIG_DIR_ENV).map(|d| Path::new(&d).join(name)),
        what: format!(
            "${CONFIG_DIR_ENV}{}",
            if set(CONFIG_DIR_ENV).is_some() {
                ""
            } else {
                ", not set"
            }
        ),
    });
    let xdg = match set("XDG_CONFIG_HOME").filter(|d| Path::new(d).is_absolute()) {
        Some(d) => Some((PathBuf::from(d), "$XDG_CONFIG_HOME/footscan")),
        None => set("HOME").map(|h| {
            (
                Path::new(&h).join(".config"),
                "~/.config/footscan ($XDG_CONFIG_HOME unset)",
            )
        }),
    };
    places.push(Place {
        path: xdg.as_ref().map(|(d, _)| d.join("footscan").join(name)),
        what: xdg.map_or("$XDG_CONFIG_HOME and $HOME unset".into(), |(_, w)| {
            w.to_string()
        }),
    });
    places.push(Place {
        path: Some(Path::new(SYSTEM_CONFIG_DIR).join(name)),
        what: "system config directory".into(),
    });
    let exe_dir = exe.and_then(Path::parent);
    places.push(Place {
        path: exe_dir.map(|d| d.join("..").join("share").join("footscan").join(name)),
        what: "../share/footscan beside the executable".into(),
    });
    let checkout = exe_dir.and_then(|d| {
        d.ancestors()
            .skip(1)
            .take(3)
            .find(|a| a.join("Cargo.toml").is_file() && a.join("config").is_dir())
    });
    places.push(Place {
        path: checkout.map(|c| c.join("config").join(name)),
        what: if checkout.is_some() {
            "config/ of the checkout the executable was built in".into()
        } else {
            "config/ of a checkout: the executable is not in one".into()
        },
    });
    places
}

/// The config file `name` means (module doc), from this process's working directory,
/// environment and executable.
pub fn find_config(name: &Path) -> Result<PathBuf, ConfigNotFound> {
    if name.is_absolute() {
        return Ok(name.to_path_buf());
    }
    let cwd = std::env::current_dir().unwrap_or_else(|_| PathBuf::from("."));
    let exe = std::env::current_exe().ok();
    let places = places_with(name, &cwd, |k| std::env::var(k).ok(), exe.as_deref());
    find_in(name, places)
}

/// The first of `places` holding a file, or the error listing them all.
pub fn find_in(name: &Path, places: Vec<Place>) -> Result<PathBuf, ConfigNotFound> {
    match places
        .iter()
        .filter_map(|p| p.path.as_ref())
        .find(|p| p.is_file())
    {
        Some(p) => Ok(p.clone()),
        None => Err(ConfigNotFound {
            name: name.to_path_buf(),
            places,
        }),
    }
}

/// Whether log lines on stderr may carry ANSI colour codes: only on a terminal, and not when
/// `NO_COLOR` is set to anything but the empty string (<https://no-color.org>).
pub fn log_colour() -> bool {
    use std::io::IsTerminal;
    std::io::stderr().is_terminal() && std::env::var_os("NO_COLOR").is_none_or(|v| v.is_empty())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn order_and_unset_places() {
        let env = |k: &str| match k {
            "HOME" => Some("/home/op".to_string()),
            "XDG_CONFIG_HOME" => Some(String::new()),
            _ => None,
        };
        let p = places_with(
            Path::new("sim.toml"),
            Path::new("/w"),
            env,
            Some(Path::new("/opt/fs/bin/footscan")),
        );
        let paths: Vec<_> = p.iter().map(|p| p.path.clone()).collect();
        assert_eq!(
            paths,
            vec![
                Some(PathBuf::from("/w/sim.toml")),
                Some(PathBuf::from("/w/config/sim.toml")),
                None,
                Some(PathBuf::from("/home/op/.config/footscan/sim.toml")),
                Some(PathBuf::from("/etc/footscan/sim.toml")),
                Some(PathBuf::from("/opt/fs/bin/../share/footscan/sim.toml")),
                None,
            ]
        );
        let e = find_in(Path::new("sim.toml"), p).unwrap_err().to_string();
        assert!(e.contains("$FOOTSCAN_CONFIG_DIR, not set"), "{e}");
        assert!(e.contains("/home/op/.config/footscan/sim.toml"), "{e}");
        // A relative XDG_CONFIG_HOME is ignored (the spec says so).
        let env = |k: &str| match k {
            "XDG_CONFIG_HOME" => Some("rel".to_string()),
            "FOOTSCAN_CONFIG_DIR" => Some("/cfg".to_string()),
            _ => None,
        };
        let p = places_with(Path::new("a.toml"), Path::new("/w"), env, None);
        assert_eq!(p[2].path, Some(PathBuf::from("/cfg/a.toml")));
        assert_eq!(p[3].path, None);
        assert_eq!(p[5].path, None);
    }

    #[test]
    fn first_existing_place_wins() {
        let d = tempfile::tempdir().unwrap();
        let (a, b) = (d.path().join("a"), d.path().join("b"));
        std::fs::create_dir_all(&a).unwrap();
        std::fs::create_dir_all(&b).unwrap();
        std::fs::write(b.join("x.toml"), "").unwrap();
        let place = |dir: &Path| Place {
            path: Some(dir.join("x.toml")),
            what: String::new(),
        };
        let found = find_in(Path::new("x.toml"), vec![place(&a), place(&b)]).unwrap();
        assert_eq!(found, b.join("x.toml"));
        std::fs::write(a.join("x.toml"), "").unwrap();
        let found = find_in(Path::new("x.toml"), vec![place(&a), place(&b)]).unwrap();
        assert_eq!(found, a.join("x.toml"));
    }
}
