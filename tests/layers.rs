//! The layer rules of ARCHITECTURE.md, checked: which workspace crate may depend on which
//! (from `cargo metadata`), and which module of the scanner library may import which (from
//! the sources). A new arrow fails here until the rule and ARCHITECTURE.md say it is wanted.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};
use std::process::Command;

/// Each workspace crate and the workspace crates it may use as normal (build) dependencies.
/// Lower layers first; a crate appears after every crate it may use.
const CRATE_RULES: &[(&str, &[&str])] = &[
    ("footscan-geom", &[]),
    ("footscan-hal", &[]),
    ("footscan-pipeline", &[]),
    ("footscan-util", &[]),
    ("footscan-fleet", &["footscan-util"]),
    ("footscan-fuzzkit", &[]),
    ("footscan-plugins", &["footscan-util"]),
    ("footscan-targets", &["footscan-geom"]),
    ("footscan-last", &["footscan-geom", "footscan-util"]),
    ("footscan-grbl", &["footscan-hal", "footscan-util"]),
    ("footscan-v4l2", &["footscan-hal"]),
    (
        "footscan-sim",
        &["footscan-hal", "footscan-targets", "footscan-geom"],
    ),
    (
        "footscan-scanner",
        &[
            "footscan-pipeline",
            "footscan-plugins",
            "footscan-sim",
            "footscan-grbl",
            "footscan-v4l2",
            "footscan-hal",
            "footscan-last",
            "footscan-targets",
            "footscan-geom",
            "footscan-util",
        ],
    ),
    (
        "footscan-insole",
        &[
            "footscan-scanner",
            "footscan-last",
            "footscan-geom",
            "footscan-util",
        ],
    ),
    (
        "footscand",
        &[
            "footscan-scanner",
            "footscan-hal",
            "footscan-sim",
            "footscan-fleet",
            "footscan-last",
            "footscan-insole",
            "footscan-geom",
            "footscan-util",
        ],
    ),
    (
        "footscan",
        &[
            "footscan-scanner",
            "footscan-plugins",
            "footscan-hal",
            "footscan-sim",
            "footscan-geom",
            "footscan-last",
            "footscan-targets",
            "footscan-fleet",
            "footscan-insole",
            "footscan-util",
        ],
    ),
    (
        "footscan-vivid",
        &[
            "footscan-scanner",
            "footscan-hal",
            "footscan-sim",
            "footscan-v4l2",
        ],
    ),
];

/// Crates nothing else in the workspace may depend on, not even for tests: the CLI (root
/// package), the daemon and the vivid harness are the top.
const TOPS: &[&str] = &["footscan", "footscand", "footscan-vivid"];

/// The scanner library's top-level modules, lowest first: a module may import only modules
/// listed before it (`crate::x` in code, doc comments aside).
const MODULE_ORDER: &[&str] = &[
    "geom",
    "detect",
    "calib",
    "scandata",
    "surface",
    "io",
    "measure",
    "cad",
    "compact",
    "lastfit",
    "lastcustom",
    "report",
    "scan",
    "startup",
];

fn workspace_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).to_path_buf()
}

/// `package name -> (normal workspace deps, all workspace deps)` from `cargo metadata`.
fn workspace_arrows() -> BTreeMap<String, (BTreeSet<String>, BTreeSet<String>)> {
    let out = Command::new(env!("CARGO"))
        .args([
            "metadata",
            "--format-version",
            "1",
            "--no-deps",
            "--offline",
        ])
        .current_dir(workspace_root())
        .output()
        .expect("cargo metadata runs");
    assert!(
        out.status.success(),
        "cargo metadata failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let meta: serde_json::Value = serde_json::from_slice(&out.stdout).expect("metadata is JSON");
    let packages = meta["packages"].as_array().expect("packages");
    let names: BTreeSet<String> = packages
        .iter()
        .map(|p| p["name"].as_str().unwrap().to_string())
        .collect();
    packages
        .iter()
        .map(|p| {
            let mut normal = BTreeSet::new();
            let mut all = BTreeSet::new();
            for d in p["dependencies"].as_array().unwrap() {
                let name = d["name"].as_str().unwrap().to_string();
                if !names.contains(&name) || name == p["name"].as_str().unwrap() {
                    continue;
                }
                if d["kind"].is_null() {
                    normal.insert(name.clone());
                }
                all.insert(name);
            }
            (p["name"].as_str().unwrap().to_string(), (normal, all))
        })
        .collect()
}

#[test]
fn crate_arrows_follow_the_layers() {
    let arrows = workspace_arrows();
    let rules: BTreeMap<&str, &[&str]> = CRATE_RULES.iter().copied().collect();
    let mut wrong = Vec::new();
    for (name, (normal, all)) in &arrows {
        let Some(allowed) = rules.get(name.as_str()) else {
            wrong.push(format!(
                "{name}: a workspace crate with no rule in tests/layers.rs"
            ));
            continue;
        };
        for d in normal {
            if !allowed.contains(&d.as_str()) {
                wrong.push(format!("{name} -> {d}: not an allowed arrow"));
            }
        }
        for d in all {
            if TOPS.contains(&d.as_str()) {
                wrong.push(format!("{name} -> {d}: nothing may depend on a top crate"));
            }
        }
    }
    for name in rules.keys() {
        if !arrows.contains_key(*name) {
            wrong.push(format!(
                "{name}: a rule for a crate the workspace does not have"
            ));
        }
    }
    assert!(
        wrong.is_empty(),
        "crate layer rules broken:\n{}",
        wrong.join("\n")
    );
    // The order of CRATE_RULES is a layering: every allowed arrow points to an earlier entry.
    for (i, (name, allowed)) in CRATE_RULES.iter().enumerate() {
        for d in *allowed {
            let j = CRATE_RULES.iter().position(|(n, _)| n == d).unwrap();
            assert!(j < i, "rule {name} -> {d} points up the list");
        }
    }
}

/// `crate::<module>` paths in the code of `text` (comment lines skipped).
fn imported_modules(text: &str) -> BTreeSet<String> {
    let mut found = BTreeSet::new();
    for line in text.lines() {
        let code = line.trim_start();
        if code.starts_with("//") {
            continue;
        }
        let code = code.split(" //").next().unwrap_or(code);
        let mut rest = code;
        while let Some(at) = rest.find("crate::") {
            let after = &rest[at + "crate::".len()..];
            if after.starts_with('{') {
                panic!("grouped `crate::{{..}}` imports hide arrows from this test: {line}");
            }
            let module: String = after
                .chars()
                .take_while(|c| c.is_ascii_alphanumeric() || *c == '_')
                .collect();
            found.insert(module);
            rest = after;
        }
    }
    found
}

fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    for e in std::fs::read_dir(dir).unwrap() {
        let p = e.unwrap().path();
        if p.is_dir() {
            rust_files(&p, out);
        } else if p.extension().is_some_and(|x| x == "rs") {
            out.push(p);
        }
    }
}

#[test]
fn scanner_modules_import_only_lower_ones() {
    let src = workspace_root().join("crates/scanner/src");
    let mut files = Vec::new();
    rust_files(&src, &mut files);
    let mut wrong = Vec::new();
    let mut seen = BTreeSet::new();
    for f in &files {
        let rel = f.strip_prefix(&src).unwrap();
        let first = rel
            .components()
            .next()
            .unwrap()
            .as_os_str()
            .to_string_lossy();
        let module = first.trim_end_matches(".rs").to_string();
        if module == "lib" {
            continue;
        }
        let Some(rank) = MODULE_ORDER.iter().position(|m| *m == module) else {
            wrong.push(format!(
                "{}: module {module} has no place in MODULE_ORDER",
                rel.display()
            ));
            continue;
        };
        seen.insert(module.clone());
        let text = std::fs::read_to_string(f).unwrap();
        for m in imported_modules(&text) {
            if m == module || m == "pipeline" {
                continue; // itself; the pipeline crate's re-export sits below every module
            }
            match MODULE_ORDER.iter().position(|x| *x == m) {
                Some(r) if r < rank => {}
                Some(_) => wrong.push(format!(
                    "{}: {module} imports {m}, a higher module",
                    rel.display()
                )),
                None => wrong.push(format!(
                    "{}: imports crate::{m}, not a module of the rule",
                    rel.display()
                )),
            }
        }
    }
    assert!(
        wrong.is_empty(),
        "scanner module rules broken:\n{}",
        wrong.join("\n")
    );
    assert_eq!(
        seen.len(),
        MODULE_ORDER.len(),
        "a module of MODULE_ORDER is gone: {seen:?}"
    );
}

#[test]
fn the_module_check_sees_imports() {
    let m = imported_modules("use crate::measure::Side;\n// crate::scan in a comment\nlet x = crate::io::f(); // crate::cad\n");
    assert_eq!(m, ["io", "measure"].into_iter().map(String::from).collect());
}
