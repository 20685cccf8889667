//! A cache of the fitted kept parts ([`super::keep::fit_part`]), one file per fit.
//!
//! A fit takes a large share of a second per part where the join itself takes milliseconds,
//! and the same lasts are joined again and again while a last maker tries planes, methods
//! and continuity on them. The fit is a function of its inputs only: the part's section
//! surface (degrees, knots, control points), the placed mesh (vertices and triangles), the
//! cutting plane, the side and depth of the part, and the fit's own rules ([`FIT_RULES`]).
//! The key is the SHA-256 of all of them, bit for bit, so a hit returns exactly what the fit
//! would. (The section surface's u parameters are means over the sections of both lasts,
//! docs/method.md 11 step 3, so a part fitted beside another partner, or at other section
//! settings, is another key.)

use super::keep::PartFit;
use footscan_geom::mesh::TriMesh;
use footscan_geom::nurbs::NurbsSurface;
use footscan_geom::plane::Plane;
use footscan_geom::P3;
use sha2::{Digest, Sha256};
use std::path::{Path, PathBuf};

/// Bumped whenever the fit's rules change (its constants are hashed too).
const FIT_RULES: &str = "keep::fit_part v6";

/// First bytes of a cache file.
const MAGIC: &[u8; 8] = b"FSFIT01\n";

/// The cache directory the command uses when none is given: `$XDG_CACHE_HOME/footscan/fits`,
/// else `$HOME/.cache/footscan/fits`; `None` without either.
pub fn default_dir() -> Option<PathBuf> {
    let base = std::env::var_os("XDG_CACHE_HOME")
        .filter(|s| !s.is_empty())
        .map(PathBuf::from)
        .or_else(|| {
            std::env::var_os("HOME")
                .filter(|s| !s.is_empty())
                .map(|h| PathBuf::from(h).join(".cache"))
        })?;
    Some(base.join("footscan").join("fits"))
}

/// The key of one fit: hex SHA-256 of every input, bit for bit, and `constants` (the fit's
/// tolerances and weights, so changing one misses).
pub fn key(
    s0: &NurbsSurface,
    mesh: &TriMesh,
    plane: &Plane,
    into_part: f64,
    within: f64,
    constants: &[f64],
) -> String {
    let mut h = Sha256::new();
    h.update(FIT_RULES.as_bytes());
    let f = |h: &mut Sha256, x: f64| h.update(x.to_bits().to_le_bytes());
    let n = |h: &mut Sha256, x: usize| h.update((x as u64).to_le_bytes());
    let p3 = |h: &mut Sha256, p: &P3| {
        for c in [p.x, p.y, p.z] {
            h.update(c.to_bits().to_le_bytes());
        }
    };
    for &c in constants {
        f(&mut h, c);
    }
    for x in [s0.degree_u, s0.degree_v, s0.nu, s0.nv] {
        n(&mut h, x);
    }
    h.update([s0.periodic_u as u8, s0.periodic_v as u8]);
    for k in [&s0.knots_u, &s0.knots_v] {
        n(&mut h, k.len());
        for &x in k {
            f(&mut h, x);
        }
    }
    for p in &s0.points {
        p3(&mut h, p);
    }
    match &s0.weights {
        Some(w) => {
            n(&mut h, w.len());
            for &x in w {
                f(&mut h, x);
            }
        }
        None => n(&mut h, usize::MAX),
    }
    n(&mut h, mesh.vertices.len());
    for v in &mesh.vertices {
        p3(&mut h, v);
    }
    n(&mut h, mesh.triangles.len());
    for t in &mesh.triangles {
        for &i in t {
            h.update(i.to_le_bytes());
        }
    }
    p3(&mut h, &plane.origin);
    for v in [plane.normal, plane.u, plane.v] {
        for c in [v.x, v.y, v.z] {
            f(&mut h, c);
        }
    }
    f(&mut h, into_part);
    f(&mut h, within);
    h.finalize().iter().map(|b| format!("{b:02x}")).collect()
}

fn path(dir: &Path, key: &str) -> PathBuf {
    dir.join(format!("{key}.fit"))
}

/// The fit stored under `key`, or `None` (no file, or one that does not read back whole).
pub fn load(dir: &Path, key: &str) -> Option<(NurbsSurface, PartFit)> {
    let bytes = std::fs::read(path(dir, key)).ok()?;
    let mut r = Reader {
        b: bytes.strip_prefix(MAGIC)?,
    };
    let json_len = r.u64()? as usize;
    let fit: PartFit = serde_json::from_slice(r.take(json_len)?).ok()?;
    let (du, dv, nu, nv) = (r.u64()?, r.u64()?, r.u64()?, r.u64()?);
    let periodic = r.take(2)?.to_vec();
    let ku = r.f64s()?;
    let kv = r.f64s()?;
    let c = r.f64s()?;
    if c.len() != 3 * (nu * nv) as usize || !r.b.is_empty() {
        return None;
    }
    let pts = c.chunks(3).map(|p| P3::new(p[0], p[1], p[2])).collect();
    let s = NurbsSurface::new(
        du as usize,
        dv as usize,
        ku,
        kv,
        nu as usize,
        nv as usize,
        pts,
        None,
    )
    .ok()?
    .with_periodic(periodic[0] == 1, periodic[1] == 1)
    .ok()?;
    Some((s, fit))
}

/// Stores a fit under `key` (written beside and renamed, so a reader never sees half a file).
/// Rational surfaces are not stored (the fit makes none).
pub fn store(dir: &Path, key: &str, s: &NurbsSurface, fit: &PartFit) -> std::io::Result<()> {
    if s.weights.is_some() {
        return Ok(());
    }
    std::fs::create_dir_all(dir)?;
    let mut b: Vec<u8> = MAGIC.to_vec();
    let json = serde_json::to_vec(fit).map_err(std::io::Error::other)?;
    b.extend((json.len() as u64).to_le_bytes());
    b.extend(&json);
    for x in [s.degree_u, s.degree_v, s.nu, s.nv] {
        b.extend((x as u64).to_le_bytes());
    }
    b.extend([s.periodic_u as u8, s.periodic_v as u8]);
    let f64s = |b: &mut Vec<u8>, xs: &mut dyn Iterator<Item = f64>, n: usize| {
        b.extend((n as u64).to_le_bytes());
        for x in xs {
            b.extend(x.to_le_bytes());
        }
    };
    f64s(&mut b, &mut s.knots_u.iter().copied(), s.knots_u.len());
    f64s(&mut b, &mut s.knots_v.iter().copied(), s.knots_v.len());
    f64s(
        &mut b,
        &mut s.points.iter().flat_map(|p| [p.x, p.y, p.z]),
        3 * s.points.len(),
    );
    footscan_util::write_atomic(&path(dir, key), &b)
}

struct Reader<'a> {
    b: &'a [u8],
}

impl<'a> Reader<'a> {
    fn take(&mut self, n: usize) -> Option<&'a [u8]> {
        if n > self.b.len() {
            return None;
        }
        let (a, rest) = self.b.split_at(n);
        self.b = rest;
        Some(a)
    }
    fn u64(&mut self) -> Option<u64> {
        Some(u64::from_le_bytes(self.take(8)?.try_into().ok()?))
    }
    fn f64s(&mut self) -> Option<Vec<f64>> {
        let n = self.u64()? as usize;
        let raw = self.take(n.checked_mul(8)?)?;
        Some(
            raw.chunks(8)
                .map(|c| f64::from_le_bytes(c.try_into().expect("8 bytes")))
                .collect(),
        )
    }
}
