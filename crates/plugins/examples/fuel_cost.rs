//! What wasmtime's limits cost a per-frame detector (issue 33; docs/method.md 14d.3 and
//! 14d.5): the same module, the same frame, called with fuel metering on (as footscan runs
//! stages), with epoch interruption instead, and with neither; each of 1,000 calls timed alone,
//! the fastest and the median printed with a hash of the output rows (two builds of a detector
//! must print the same). `FUEL_COST_LIT=0.5` lights only the first half of the rows, as a foot
//! lights part of a frame. Not a test; run by hand:
//!
//! ```text
//! clang --target=wasm32 -O2 -msimd128 -nostdlib -Wl,--no-entry -I examples/plugins \
//!     -o /tmp/cog.wasm examples/plugins/cog-wasm/cog.c
//! cargo run --release -p footscan-plugins --example fuel_cost -- /tmp/cog.wasm
//! ```

use std::time::Instant;
use wasmtime::{Config, Engine, Instance, Module, Store};

fn main() {
    let path = std::env::args()
        .nth(1)
        .expect("usage: fuel_cost MODULE.wasm");
    let (w, h) = (1280i32, 1024i32);
    // A frame with a bright line wandering across the rows over a dim, uneven background.
    let mut px = vec![0u8; (w * h) as usize];
    // FUEL_COST_LIT: the share of rows the line crosses (a foot covers part of the frame).
    let lit: f64 = std::env::var("FUEL_COST_LIT")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(1.0);
    for r in 0..h as usize {
        let on = (r as f64) < lit * h as f64;
        let centre = 400.0 + 200.0 * (r as f64 / 97.0).sin();
        for c in 0..w as usize {
            let d = (c as f64 - centre) / 2.5;
            let bg = 8 + ((r * 7 + c * 13) % 11) as u32;
            px[r * w as usize + c] =
                (bg + (if on { 200.0 * (-d * d).exp() } else { 0.0 }) as u32).min(255) as u8;
        }
    }
    // The same frame as Gray16 (value x 4, little-endian): both of cog.c's paths.
    let px16: Vec<u8> = px
        .iter()
        .flat_map(|&v| (v as u16 * 4).to_le_bytes())
        .collect();
    for (bpp, px, fuel, epoch) in [
        (1, &px, true, false),
        (1, &px, false, true),
        (1, &px, false, false),
        (2, &px16, true, false),
    ] {
        let mut cfg = Config::new();
        cfg.consume_fuel(fuel);
        cfg.epoch_interruption(epoch);
        let engine = Engine::new(&cfg).unwrap();
        let module = Module::from_file(&engine, &path).unwrap();
        let mut store = Store::new(&engine, ());
        if fuel {
            store.set_fuel(u64::MAX / 2).unwrap();
        }
        if epoch {
            store.set_epoch_deadline(1 << 40);
        }
        let inst = Instance::new(&mut store, &module, &[]).unwrap();
        let mem = inst.get_memory(&mut store, "memory").unwrap();
        let alloc = inst
            .get_typed_func::<i32, i32>(&mut store, "footscan_alloc")
            .unwrap();
        let param = inst
            .get_typed_func::<(i32, i32, f64), i32>(&mut store, "footscan_param")
            .unwrap();
        let detect = inst
            .get_typed_func::<(i32, i32, i32, i32, i32), i32>(&mut store, "footscan_detect")
            .unwrap();
        let key = alloc.call(&mut store, 16).unwrap();
        mem.data_mut(&mut store)[key as usize..key as usize + 9].copy_from_slice(b"threshold");
        assert_eq!(param.call(&mut store, (key, 9, 30.0)).unwrap(), 0);
        let inp = alloc.call(&mut store, w * h * bpp).unwrap();
        let out = alloc.call(&mut store, h * 24).unwrap();
        mem.data_mut(&mut store)[inp as usize..(inp + w * h * bpp) as usize].copy_from_slice(px);
        // Each call timed on its own: on a shared machine the fastest calls are the ones no other
        // process interrupted, so the minimum and the median say more than a round's mean.
        let n = 1000;
        let mut t_us: Vec<f64> = (0..n)
            .map(|_| {
                let t = Instant::now();
                let rows = detect.call(&mut store, (inp, w, h, bpp, out)).unwrap();
                assert_eq!(rows, h);
                t.elapsed().as_secs_f64() * 1e6
            })
            .collect();
        t_us.sort_by(f64::total_cmp);
        // FNV-1a of the output rows: two builds of a detector must print the same.
        let rows = &mem.data(&store)[out as usize..(out + h * 24) as usize];
        let hash = rows.iter().fold(0xcbf2_9ce4_8422_2325u64, |a, &b| {
            (a ^ b as u64).wrapping_mul(0x100_0000_01b3)
        });
        println!(
            "Gray{} {}: {:.1} us min, {:.1} us median per 1280x1024 frame ({n} calls), rows {hash:016x}",
            8 * bpp,
            match (fuel, epoch) {
                (true, _) => "fuel metering      ",
                (_, true) => "epoch interruption ",
                _ => "no limit           ",
            },
            t_us[0],
            t_us[n / 2]
        );
    }
}
