//! Fuzzing of the mesh readers (STL ASCII and binary, OBJ, PLY ascii and binary) on stable
//! Rust: proptest feeds them arbitrary bytes and mutations of valid files, and a counting
//! global allocator measures the most each call holds at once.
//! Every reader must return (Ok or a clear error, never a panic) and hold at most
//! [`RATIO`] x its input size plus [`FIXED`] bytes, whatever the bytes.
//!
//! The normal test run tries a bounded number of cases (a few seconds); a longer run:
//!
//! ```text
//! FOOTSCAN_FUZZ_CASES=200000 cargo test -p footscan-geom --release --test fuzz_readers
//! ```
//!
//! Inputs that failed are kept as regression cases (`regressions` below and proptest's
//! `fuzz_readers.proptest-regressions`).

use footscan_fuzzkit::{peak_of, Counting};
use footscan_geom::mesh::{cloud, TriMesh};
use proptest::prelude::*;
use std::path::Path;

/// Bytes held per byte of input, at most.
const RATIO: usize = 4;
/// Bytes held whatever the input (error messages, the header's elements, small buffers).
const FIXED: usize = 64 * 1024;

// The allocator that counts what each thread holds (crates/fuzzkit).
#[global_allocator]
static A: Counting = Counting;

type Reader = fn(&[u8]);

fn readers() -> [(&'static str, Reader); 4] {
    [
        ("stl", |b| {
            drop(TriMesh::parse_stl(b, Path::new("fuzz.stl")))
        }),
        ("obj", |b| {
            drop(TriMesh::parse_obj(b, Path::new("fuzz.obj")))
        }),
        ("ply", |b| {
            drop(TriMesh::parse_ply(b, Path::new("fuzz.ply")))
        }),
        // The point-cloud reader's text (the mesh made from the points is
        // `cloud_load_grows_by_the_points_alone` below).
        ("xyz", |b| drop(cloud::parse_xyz_bytes(b))),
    ]
}

/// Run every reader on `bytes`: none panics, none holds more than the bound.
fn check(bytes: &[u8]) -> Result<(), String> {
    for (name, read) in readers() {
        let (peak, panicked) = peak_of(|| read(bytes));
        if panicked {
            return Err(format!("{name} reader panicked on {} bytes", bytes.len()));
        }
        let bound = RATIO * bytes.len() + FIXED;
        if peak > bound {
            return Err(format!(
                "{name} reader held {peak} bytes for {} bytes of input (bound {bound})",
                bytes.len()
            ));
        }
    }
    Ok(())
}

/// Valid files of each format, to mutate.
fn seeds() -> Vec<Vec<u8>> {
    let m = TriMesh::cuboid(
        footscan_geom::P3::new(0.0, 0.0, 0.0),
        footscan_geom::P3::new(1.0, 2.0, 3.0),
    );
    vec![
        m.to_stl_binary(),
        m.to_stl_ascii("seed").into_bytes(),
        m.to_obj().into_bytes(),
        m.to_ply(false),
        m.to_ply(true),
    ]
}

/// A seed with some bytes replaced, inserted or cut.
fn mutated() -> impl Strategy<Value = Vec<u8>> {
    let edits = prop::collection::vec((0usize..1 << 16, any::<u8>(), 0u8..4), 1..12);
    (0..seeds().len(), edits).prop_map(|(i, edits)| {
        let mut b = seeds()[i].clone();
        for (at, byte, kind) in edits {
            if b.is_empty() {
                b.push(byte);
                continue;
            }
            let at = at % b.len();
            match kind {
                0 => b[at] = byte,
                1 => b.insert(at, byte),
                2 => b.truncate(at),
                _ => {
                    // A digit run: counts and indices far from the real ones.
                    let digits = format!("{}", (byte as u64).pow(5) * 7919);
                    for (k, d) in digits.bytes().enumerate() {
                        b.insert((at + k).min(b.len()), d);
                    }
                }
            }
        }
        b
    })
}

/// Text made of the formats' own words and numbers, in any order.
fn wordy() -> impl Strategy<Value = Vec<u8>> {
    let word = prop_oneof![
        Just("solid".to_string()),
        Just("facet normal 0 0 1".into()),
        Just("outer loop".into()),
        Just("vertex".into()),
        Just("endloop".into()),
        Just("endfacet".into()),
        Just("v".into()),
        Just("f".into()),
        Just("ply".into()),
        Just("format ascii 1.0".into()),
        Just("format binary_little_endian 1.0".into()),
        Just("element vertex".into()),
        Just("element face".into()),
        Just("property float x".into()),
        Just("property float y".into()),
        Just("property float z".into()),
        Just("property list uchar int vertex_indices".into()),
        Just("property list uint uint vertex_indices".into()),
        Just("property list double double vertex_indices".into()),
        Just("end_header".into()),
        Just("\n".into()),
        (-5i64..5).prop_map(|n| n.to_string()),
        any::<u32>().prop_map(|n| n.to_string()),
        Just("1e300".into()),
        Just("4294967295".into()),
        Just("-1".into()),
        Just("nan".into()),
        any::<f32>().prop_map(|x| x.to_string()),
    ];
    prop::collection::vec(word, 0..200).prop_map(|w| w.join(" ").into_bytes())
}

fn cases() -> u32 {
    std::env::var("FOOTSCAN_FUZZ_CASES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(1500)
}

proptest! {
    #![proptest_config(ProptestConfig { cases: cases(), ..ProptestConfig::default() })]

    #[test]
    fn arbitrary_bytes(b in prop::collection::vec(any::<u8>(), 0..2048)) {
        check(&b).map_err(TestCaseError::fail)?;
    }

    #[test]
    fn mutated_files(b in mutated()) {
        check(&b).map_err(TestCaseError::fail)?;
    }

    #[test]
    fn format_words(b in wordy()) {
        check(&b).map_err(TestCaseError::fail)?;
    }
}

/// Inputs the fuzzing found, kept.
#[test]
fn regressions() {
    let cases: &[&[u8]] = &[
        // A list count of 1e300 in an ASCII PLY: `Vec::with_capacity(1e300 as usize)`.
        b"ply\nformat ascii 1.0\nelement face 1\nproperty list double int vertex_indices\nend_header\n1e300 0 1 2\n",
        // A list count of 4294967295 with no body behind it.
        b"ply\nformat binary_little_endian 1.0\nelement face 1\nproperty list uint uint vertex_indices\nend_header\n\xff\xff\xff\xff",
    ];
    for c in cases {
        check(c).unwrap();
    }
}

/// Found by cargo-fuzz (fuzz/, mesh_ply): an element of no property said to have
/// 499999999999 records, whose records take no byte, kept the reader looping for hours. It
/// must answer (an error) at once; run on a thread so that a relapse fails instead of hanging.
#[test]
fn a_huge_count_of_empty_records_is_refused_at_once() {
    let input: &[u8] =
        b"ply\nformat ascii 1.0\ncomment z\nelement f\x01\x00\x00\x0ea 499999999999 0 0\n\
        1 999)ertyes\nend_header\n0 0\n";
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        let r = TriMesh::parse_ply(input, Path::new("empty-records.ply"));
        let _ = tx.send(r.map(|_| ()).map_err(|e| e.to_string()));
    });
    let r = rx
        .recv_timeout(std::time::Duration::from_secs(10))
        .expect("the PLY reader did not answer within 10 s");
    let e = r.expect_err("a count no body can hold is refused");
    assert!(e.contains("499999999999"), "{e}");
}

/// The densest inputs each format allows: the most a reader holds per input byte, printed
/// (docs/method.md, issue 37), and checked against the bound.
#[test]
fn densest_inputs_stay_within_the_bound() {
    let n = 20_000;
    let mut obj_fan = b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1".to_vec();
    for _ in 0..n {
        obj_fan.extend_from_slice(b" 1");
    }
    // Nine distinct one-digit corners: the densest a face of distinct corners can be.
    let mut obj_nine = Vec::new();
    for _ in 0..9 {
        obj_nine.extend_from_slice(b"v 0 0 0\n");
    }
    for _ in 0..n / 10 {
        obj_nine.extend_from_slice(b"f 1 2 3 4 5 6 7 8 9\n");
    }
    // The same faces with 8 triangles per vertex, the most the reader takes.
    let mut obj_nine_capped = Vec::new();
    let v = 2000;
    for _ in 0..v {
        obj_nine_capped.extend_from_slice(b"v 0 0 0\n");
    }
    for _ in 0..8 * v / 7 {
        obj_nine_capped.extend_from_slice(b"f 1 2 3 4 5 6 7 8 9\n");
    }
    let mut xyz = Vec::new();
    for _ in 0..n {
        xyz.extend_from_slice(b"1 2 3\n");
    }
    let mut obj_vertices = Vec::new();
    for _ in 0..n {
        obj_vertices.extend_from_slice(b"v 0 0 0\n");
    }
    let mut ply_uchar = format!(
        "ply\nformat binary_little_endian 1.0\nelement vertex {n}\nproperty uchar x\n\
         property uchar y\nproperty uchar z\nend_header\n"
    )
    .into_bytes();
    ply_uchar.extend(std::iter::repeat_n(7u8, 3 * n));
    let mut ply_faces = b"ply\nformat binary_little_endian 1.0\nelement vertex 3\n\
        property short x\nproperty short y\nproperty short z\nelement face 1\n\
        property list ushort uchar vertex_indices\nend_header\n"
        .to_vec();
    ply_faces.extend([0u8; 18]);
    ply_faces.extend(u16::MAX.to_le_bytes());
    ply_faces.extend(std::iter::repeat_n(0u8, u16::MAX as usize));
    let mut stl_ascii = b"solid s\n".to_vec();
    for _ in 0..n / 10 {
        stl_ascii
            .extend_from_slice(b"outer loop\nvertex 0 0 0\nvertex 0 0 0\nvertex 0 0 0\nendloop\n");
    }
    let m = TriMesh::cuboid(
        footscan_geom::P3::new(0.0, 0.0, 0.0),
        footscan_geom::P3::new(1.0, 1.0, 1.0),
    );
    let mut stl_binary = m.to_stl_binary();
    for _ in 0..n / 12 {
        stl_binary.extend_from_within(84..84 + 50 * 12);
    }
    let count = ((stl_binary.len() - 84) / 50) as u32;
    stl_binary[80..84].copy_from_slice(&count.to_le_bytes());
    let mut worst = Vec::new();
    for (name, bytes, read) in [
        ("OBJ fan", &obj_fan, readers()[1].1),
        ("OBJ nine-corner faces", &obj_nine, readers()[1].1),
        (
            "OBJ nine-corner faces, 8 triangles a vertex",
            &obj_nine_capped,
            readers()[1].1,
        ),
        ("XYZ points", &xyz, readers()[3].1),
        ("OBJ vertices", &obj_vertices, readers()[1].1),
        ("PLY uchar vertices", &ply_uchar, readers()[2].1),
        ("PLY one long face", &ply_faces, readers()[2].1),
        ("STL ASCII", &stl_ascii, readers()[0].1),
        ("STL binary", &stl_binary, readers()[0].1),
    ] {
        let (peak, panicked) = peak_of(|| read(bytes));
        assert!(!panicked, "{name}");
        let ratio = peak as f64 / bytes.len() as f64;
        worst.push(format!(
            "{name}: {peak} bytes for {} ({ratio:.2}x)",
            bytes.len()
        ));
    }
    println!("{}", worst.join("\n"));
    for (name, bytes) in [
        ("OBJ fan", &obj_fan),
        ("OBJ nine-corner faces", &obj_nine),
        (
            "OBJ nine-corner faces, 8 triangles a vertex",
            &obj_nine_capped,
        ),
        ("XYZ points", &xyz),
        ("OBJ vertices", &obj_vertices),
        ("PLY uchar vertices", &ply_uchar),
        ("PLY one long face", &ply_faces),
        ("STL ASCII", &stl_ascii),
        ("STL binary", &stl_binary),
    ] {
        check(bytes).map_err(|e| format!("{name}: {e}")).unwrap();
    }
}

/// The seeds themselves read, and within the bound: the bound is not one only errors meet.
#[test]
fn valid_files_read_within_the_bound() {
    for s in seeds() {
        check(&s).unwrap();
    }
}

/// Dense faces over few vertices make more triangles than any surface has per vertex: they
/// are refused, naming the line, before they cost more than the bound (issue 37: nine-corner
/// faces of one-digit indices held 4.20x their text).
#[test]
fn more_triangles_than_a_surface_has_are_refused() {
    let mut obj = Vec::new();
    for _ in 0..9 {
        obj.extend_from_slice(b"v 0 0 0\n");
    }
    for _ in 0..2000 {
        obj.extend_from_slice(b"f 1 2 3 4 5 6 7 8 9\n");
    }
    let e = TriMesh::parse_obj(&obj, Path::new("dense.obj"))
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("dense.obj") && e.contains("line 20") && e.contains("8 triangles per vertex"),
        "{e}"
    );
    // A real polygon mesh is far from the cap: the cuboid as quads.
    let quads = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 0 1\nv 1 0 1\nv 1 1 1\nv 0 1 1\n\
        f 1 4 3 2\nf 5 6 7 8\nf 1 2 6 5\nf 2 3 7 6\nf 3 4 8 7\nf 4 1 5 8\n";
    let m = TriMesh::parse_obj(quads.as_bytes(), Path::new("quads.obj")).unwrap();
    assert_eq!(m.triangles.len(), 12);
}

/// Points on an ellipsoid the size of a last, as the shortest XYZ text can write them
/// (integers, one space): what loading them holds beyond a fixed amount (the mesh, its
/// search tree) grows by no more than 4x the text. Two sizes: the growth between them
/// is what the points cost.
#[test]
fn cloud_load_grows_by_the_points_alone() {
    let text = |n: usize| {
        let mut t = Vec::new();
        let (mut i, mut k) = (0usize, 0usize);
        while k < n {
            // A Fibonacci sphere stretched to 260 x 100 x 110 mm, rounded to the millimetre
            // (duplicates kept: a scan repeats points too).
            let z = 1.0 - 2.0 * (i as f64 + 0.5) / n as f64;
            let r = (1.0 - z * z).sqrt();
            let th = i as f64 * 2.399_963_229_728_653;
            let p = [130.0 * z, 50.0 * r * th.cos(), 55.0 * r * th.sin()];
            t.extend_from_slice(format!("{:.0} {:.0} {:.0}\n", p[0], p[1], p[2]).as_bytes());
            i += 1;
            k += 1;
        }
        t
    };
    let mut seen = Vec::new();
    for n in [5_000, 40_000] {
        let t = text(n);
        let (peak, panicked) = peak_of(|| {
            let (m, fit) = cloud::last_from_xyz(&t).expect("an ellipsoid's points read");
            assert_eq!(fit.points, n);
            assert!(fit.rms_mm < 1.0, "{fit:?}");
            drop(m);
        });
        assert!(!panicked);
        println!(
            "{n} points, {} bytes of text: held {peak} bytes ({:.2}x)",
            t.len(),
            peak as f64 / t.len() as f64
        );
        seen.push((t.len(), peak));
    }
    let (d_in, d_held) = (seen[1].0 - seen[0].0, seen[1].1 - seen[0].1);
    println!(
        "growth: {d_held} bytes held for {d_in} more bytes of text ({:.2}x)",
        d_held as f64 / d_in as f64
    );
    assert!(d_held <= RATIO * d_in, "{d_held} for {d_in}");
}
