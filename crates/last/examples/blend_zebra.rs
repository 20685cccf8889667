//! The blend beside the Gordon join on both real pairs, with the zebra pictures (`cargo run
//! --release -p footscan-last --example blend_zebra -- DIR`): the rows of `footscan bench
//! join` for the Gordon join at 45 deg and the linear and polynomial blends, and
//! DIR/zebra_PAIR.png (Gordon left, polynomial blend right), without building the command.

use footscan_last::blend::weight::Weight;
use footscan_last::blend::{Blend, Skin};
use footscan_last::join::{compare, study};
use std::path::PathBuf;

fn main() {
    let data = std::env::var_os("FOOTSCAN_DATA")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data"));
    let out = std::env::args().nth(1).map(PathBuf::from);
    let pairs = study::real_pairs(&data).expect("real last pairs (set FOOTSCAN_DATA)");
    let methods = vec![
        compare::Method::Gordon { angle_deg: 45.0 },
        compare::Method::Blend(Blend::Fixed(Weight::Linear), Skin::One),
        compare::Method::Blend(Blend::Fixed(Weight::Poly), Skin::One),
    ];
    let (rows, pics) = compare::run(&pairs, &methods, 1, out.is_some()).unwrap();
    print!("{}", compare::table(&rows));
    if let Some(out) = out {
        std::fs::create_dir_all(&out).unwrap();
        for pair in &pairs {
            let p = compare::pair_zebra_png(&out, &pair.name, &pics).unwrap();
            eprintln!("wrote {}", p.display());
        }
    }
}
