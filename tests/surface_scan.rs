//! The plantar model on a real simulated scan: the `model.bezier` stage writes a closed
//! model.stl, and the network represents the simulator's analytic sole within 0.05 mm RMS.

use footscan::scan::{LoadedConfig, ScanGrid};
use footscan::surface::compare::{eval_params, representation_errors, rms, Fitted};
use footscan::surface::{BezierNetwork, PointGrid};
use footscan_geom::mesh::TriMesh;
use footscan_geom::P3;
use footscan_sim::foot::Foot;
use std::collections::HashMap;
use std::path::Path;

mod common;

/// Read a binary STL back, merging vertices with identical coordinates.
fn read_stl(p: &Path) -> TriMesh {
    let b = std::fs::read(p).unwrap();
    let n = u32::from_le_bytes(b[80..84].try_into().unwrap()) as usize;
    assert_eq!(b.len(), 84 + 50 * n, "STL size");
    let mut index: HashMap<[u32; 3], u32> = HashMap::new();
    let mut mesh = TriMesh::default();
    for k in 0..n {
        let at = 84 + 50 * k + 12;
        let mut tri = [0u32; 3];
        for (c, t) in tri.iter_mut().enumerate() {
            let f = |q: usize| {
                let o = at + 12 * c + 4 * q;
                f32::from_le_bytes(b[o..o + 4].try_into().unwrap())
            };
            let key = [f(0).to_bits(), f(1).to_bits(), f(2).to_bits()];
            *t = *index.entry(key).or_insert_with(|| {
                mesh.vertices
                    .push(P3::new(f(0) as f64, f(1) as f64, f(2) as f64));
                (mesh.vertices.len() - 1) as u32
            });
        }
        mesh.triangles.push(tri);
    }
    mesh
}

#[test]
fn simulated_scan_model_meets_the_representation_target() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let cfg = LoadedConfig::load(&root.join("config/sim.toml")).unwrap();
    // The package's shared default scan (tests/common) of this config.
    let dir = common::default_scan();
    let s = common::summary(dir);
    assert_eq!(s["status"], "complete", "{}", s["reason"]);

    // The stage's mesh: closed and consistently oriented once read back from the STL.
    let mesh = read_stl(&dir.join("model.stl"));
    assert!(mesh.triangles.len() > 100_000);
    mesh.check_closed().unwrap();
    assert!(mesh.volume() > 10_000.0);

    let grid = ScanGrid::load(&dir.join("grid.bin")).unwrap();
    let foot = Foot::new(cfg.config.sim.foot.clone()).unwrap();
    let truth = |x: f64, y: f64| foot.height(x, y);
    let full = PointGrid::from_scan(&grid);
    let t1 = full.subsample(&full.even_subsample(88, 91).unwrap());
    for (name, g, bound) in [("full", &full, 0.05), ("table1", &t1, 0.08)] {
        let net = BezierNetwork::build(g).unwrap();
        let params = eval_params(&net, 4, 8);
        let fit = Fitted::Network(net);
        let e = representation_errors(&fit, &params, &truth);
        assert!(e.len() as f64 > 0.99 * params.len() as f64, "{name}");
        let r = rms(&e);
        assert!(r <= bound, "{name}: representation RMS {r} mm");
    }
}
