//! Mesh files: STL (binary and ASCII), PLY (ASCII, binary little- and big-endian) and OBJ.
//!
//! Writers keep every coordinate exactly: ASCII formats print the shortest decimal that
//! reads back to the same f64, binary PLY stores doubles. Binary STL stores f32 by
//! definition, so it is exact only for coordinates that are f32 values.

use super::{MeshError, TriMesh};
use crate::P3;
use std::path::{Path, PathBuf};

/// A mesh file format.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Format {
    StlBinary,
    StlAscii,
    PlyAscii,
    PlyBinary,
    Obj,
}

/// Which STL flavour a file holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum StlKind {
    Binary,
    Ascii,
}

fn parse_err(path: &Path, what: impl Into<String>) -> MeshError {
    MeshError::Parse {
        path: path.to_path_buf(),
        what: what.into(),
    }
}

impl Format {
    /// The format for a file name's extension (binary for .stl and .ply).
    pub fn from_path(path: &Path) -> Result<Format, MeshError> {
        let ext = path
            .extension()
            .and_then(|e| e.to_str())
            .unwrap_or("")
            .to_ascii_lowercase();
        match ext.as_str() {
            "stl" => Ok(Format::StlBinary),
            "ply" => Ok(Format::PlyBinary),
            "obj" => Ok(Format::Obj),
            _ => Err(MeshError::UnknownFormat {
                path: path.to_path_buf(),
                ext,
            }),
        }
    }
}

impl TriMesh {
    /// Reads a mesh file, the format chosen by extension (.stl, .ply, .obj) and, for STL and
    /// PLY, the flavour by content. STL corners at equal positions are merged.
    pub fn read(path: impl AsRef<Path>) -> Result<TriMesh, MeshError> {
        let path = path.as_ref();
        let fmt = Format::from_path(path)?;
        let bytes = std::fs::read(path).map_err(|source| MeshError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        match fmt {
            Format::StlBinary | Format::StlAscii => TriMesh::parse_stl(&bytes, path).map(|r| r.0),
            Format::PlyAscii | Format::PlyBinary => TriMesh::parse_ply(&bytes, path),
            Format::Obj => TriMesh::parse_obj(&bytes, path),
        }
    }

    /// Writes the mesh in `format` (to a temporary file renamed into place, so a failed write
    /// leaves no partial file).
    pub fn write(&self, path: impl AsRef<Path>, format: Format) -> Result<(), MeshError> {
        let path = path.as_ref();
        let bytes = match format {
            Format::StlBinary => self.to_stl_binary(),
            Format::StlAscii => self.to_stl_ascii("footscan").into_bytes(),
            Format::PlyAscii => self.to_ply(false),
            Format::PlyBinary => self.to_ply(true),
            Format::Obj => self.to_obj().into_bytes(),
        };
        let mut tmp = PathBuf::from(path);
        let mut name = path.file_name().unwrap_or_default().to_os_string();
        name.push(".tmp");
        tmp.set_file_name(name);
        let io = |source| MeshError::Io {
            path: path.to_path_buf(),
            source,
        };
        std::fs::write(&tmp, bytes).map_err(io)?;
        std::fs::rename(&tmp, path).map_err(io)
    }

    /// Parses STL bytes (binary when the size matches the triangle count in the header,
    /// otherwise ASCII); `path` names the input in errors.
    pub fn parse_stl(bytes: &[u8], path: &Path) -> Result<(TriMesh, StlKind), MeshError> {
        if bytes.len() >= 84 {
            let n = u32::from_le_bytes(bytes[80..84].try_into().unwrap()) as usize;
            if bytes.len() as u64 == 84 + 50 * n as u64 {
                // The records are read twice (checked, then merged) rather than held as a
                // soup beside the mesh: 72 bytes a triangle fewer held.
                let tri = |t: usize| {
                    let rec = &bytes[84 + 50 * t..84 + 50 * t + 50];
                    let f = |k: usize| {
                        f32::from_le_bytes(rec[4 * k..4 * k + 4].try_into().unwrap()) as f64
                    };
                    [0, 1, 2].map(|c| P3::new(f(3 + 3 * c), f(4 + 3 * c), f(5 + 3 * c)))
                };
                if let Some(t) =
                    (0..n).find(|&t| tri(t).iter().any(|p| !p.iter().all(|c| c.is_finite())))
                {
                    return Err(parse_err(
                        path,
                        format!("facet {t} has a non-finite coordinate"),
                    ));
                }
                return Ok((TriMesh::from_triangles(n, (0..n).map(tri)), StlKind::Binary));
            }
        }
        let text = std::str::from_utf8(bytes).map_err(|_| {
            parse_err(
                path,
                format!(
                    "not an STL file: {} bytes is not 84 + 50 x (its triangle count) for binary STL, \
                     and it is not ASCII text",
                    bytes.len()
                ),
            )
        })?;
        if !text.trim_start().starts_with("solid") {
            return Err(parse_err(
                path,
                "not an STL file: neither binary STL (size does not match the triangle count) nor \
                 ASCII STL (does not start with 'solid')",
            ));
        }
        // Counted first, so the soup is allocated once at its size (no doubling).
        let facets = text
            .lines()
            .filter(|l| l.split_whitespace().next() == Some("endloop"))
            .count();
        let mut soup = Vec::with_capacity(facets);
        let mut cur: Vec<P3> = Vec::with_capacity(3);
        let mut in_loop = false;
        for (ln, line) in text.lines().enumerate() {
            let mut tok = line.split_whitespace();
            match tok.next() {
                Some("outer") => {
                    in_loop = true;
                    cur.clear();
                }
                Some("vertex") => {
                    let xyz: Vec<f64> = tok
                        .map(|s| s.parse::<f64>())
                        .collect::<Result<_, _>>()
                        .map_err(|_| {
                            parse_err(
                                path,
                                format!("line {}: bad number in {:?}", ln + 1, line.trim()),
                            )
                        })?;
                    if xyz.len() != 3 || !in_loop {
                        return Err(parse_err(
                            path,
                            format!(
                                "line {}: expected 'vertex x y z' inside 'outer loop'",
                                ln + 1
                            ),
                        ));
                    }
                    cur.push(P3::new(xyz[0], xyz[1], xyz[2]));
                }
                Some("endloop") => {
                    if cur.len() != 3 {
                        return Err(parse_err(
                            path,
                            format!(
                                "line {}: a facet has {} vertices; STL facets have 3",
                                ln + 1,
                                cur.len()
                            ),
                        ));
                    }
                    if soup.len() == soup.capacity() {
                        return Err(parse_err(path, "more facets than counted"));
                    }
                    soup.push([cur[0], cur[1], cur[2]]);
                    in_loop = false;
                }
                _ => {}
            }
        }
        check_finite_soup(&soup, path)?;
        Ok((TriMesh::from_soup(&soup), StlKind::Ascii))
    }

    /// Binary STL (f32 coordinates, facet normals from the corners).
    pub fn to_stl_binary(&self) -> Vec<u8> {
        let mut out = Vec::with_capacity(84 + 50 * self.triangles.len());
        let mut header = [b' '; 80];
        let h = b"binary STL written by footscan-geom, millimetres";
        header[..h.len()].copy_from_slice(h);
        out.extend_from_slice(&header);
        out.extend_from_slice(&(self.triangles.len() as u32).to_le_bytes());
        for t in 0..self.triangles.len() {
            let n = self.face_normal(t);
            for c in n.iter() {
                out.extend_from_slice(&(*c as f32).to_le_bytes());
            }
            for p in self.corners(t) {
                for c in p.iter() {
                    out.extend_from_slice(&(*c as f32).to_le_bytes());
                }
            }
            out.extend_from_slice(&[0, 0]);
        }
        out
    }

    /// ASCII STL; coordinates in shortest round-trip exponent form, so reading it back gives
    /// the same f64 values.
    pub fn to_stl_ascii(&self, name: &str) -> String {
        use std::fmt::Write;
        let mut s = String::with_capacity(260 * self.triangles.len() + 64);
        let _ = writeln!(s, "solid {name}");
        for t in 0..self.triangles.len() {
            let n = self.face_normal(t);
            let _ = writeln!(s, "  facet normal {:e} {:e} {:e}", n.x, n.y, n.z);
            s.push_str("    outer loop\n");
            for p in self.corners(t) {
                let _ = writeln!(s, "      vertex {:e} {:e} {:e}", p.x, p.y, p.z);
            }
            s.push_str("    endloop\n  endfacet\n");
        }
        let _ = writeln!(s, "endsolid {name}");
        s
    }

    /// PLY with vertex (x, y, z as double) and face (list uchar int vertex_indices) elements.
    pub fn to_ply(&self, binary: bool) -> Vec<u8> {
        use std::fmt::Write;
        let mut h = String::new();
        let _ = write!(
            h,
            "ply\nformat {} 1.0\ncomment footscan-geom, millimetres\nelement vertex {}\n\
             property double x\nproperty double y\nproperty double z\nelement face {}\n\
             property list uchar int vertex_indices\nend_header\n",
            if binary {
                "binary_little_endian"
            } else {
                "ascii"
            },
            self.vertices.len(),
            self.triangles.len()
        );
        let mut out = h.into_bytes();
        if binary {
            for p in &self.vertices {
                for c in p.iter() {
                    out.extend_from_slice(&c.to_le_bytes());
                }
            }
            for t in &self.triangles {
                out.push(3);
                for i in t {
                    out.extend_from_slice(&(*i as i32).to_le_bytes());
                }
            }
        } else {
            let mut s = String::new();
            for p in &self.vertices {
                let _ = writeln!(s, "{} {} {}", p.x, p.y, p.z);
            }
            for t in &self.triangles {
                let _ = writeln!(s, "3 {} {} {}", t[0], t[1], t[2]);
            }
            out.extend_from_slice(s.as_bytes());
        }
        out
    }

    /// Wavefront OBJ (v and f lines, 1-based indices).
    pub fn to_obj(&self) -> String {
        use std::fmt::Write;
        let mut s = String::from("# footscan-geom, millimetres\n");
        for p in &self.vertices {
            let _ = writeln!(s, "v {} {} {}", p.x, p.y, p.z);
        }
        for t in &self.triangles {
            let _ = writeln!(s, "f {} {} {}", t[0] + 1, t[1] + 1, t[2] + 1);
        }
        s
    }

    /// Parses OBJ: `v` and `f` lines (other statements ignored); `f a/b/c ...` polygons are
    /// fan-triangulated, negative indices count back from the latest vertex.
    pub fn parse_obj(bytes: &[u8], path: &Path) -> Result<TriMesh, MeshError> {
        // Lines other than `v` and `f` are skipped unread (a material name need not be
        // UTF-8), so the text is taken a line at a time, never copied whole.
        let lines = || bytes.split(|&b| b == b'\n');
        let word = |l: &[u8]| -> Option<u8> {
            let mut t = l
                .split(|b| b.is_ascii_whitespace())
                .filter(|t| !t.is_empty());
            match t.next()? {
                b"v" => Some(b'v'),
                b"f" => Some(b'f'),
                _ => None,
            }
        };
        // A first pass counts what the second stores, so both lists are allocated once at
        // their size (no doubling): at most 3 and 4 bytes held per byte of `v` and `f`
        // lines.
        let (mut nv, mut nt) = (0usize, 0usize);
        for l in lines() {
            match word(l) {
                Some(b'v') => nv += 1,
                Some(b'f') => {
                    let corners = l
                        .split(|b| b.is_ascii_whitespace())
                        .filter(|t| !t.is_empty())
                        .count()
                        - 1;
                    // A face of distinct corners spends at least 3 bytes on each beyond its
                    // first nine (one-digit indices): never reserve more triangles than that
                    // (a line repeating `1` is refused below).
                    nt += corners
                        .min(ply::MAX_CORNERS)
                        .saturating_sub(2)
                        .min((l.len() + 8) / 3);
                }
                _ => {}
            }
        }
        // No surface has more than a few triangles per vertex (a closed one about 2, Euler;
        // a doubled or much-cut one a few more). Capping them at 8 also caps what a file of
        // few vertices and many dense faces costs: a nine-corner face of one-digit indices
        // (`f 1 2 3 4 5 6 7 8 9`, 20 bytes) makes 7 triangles (84 bytes), 4.2x its text,
        // but a vertex's 24 bytes cost at most its 8-byte line's 3x, and 8 triangles a
        // vertex keep the whole within 4x (docs/method.md 14.2.2).
        let cap = nv.saturating_mul(MAX_TRIANGLES_PER_VERTEX);
        let mut m = TriMesh::default();
        m.vertices.reserve_exact(nv);
        m.triangles.reserve_exact(nt.min(cap));
        for (ln, raw) in lines().enumerate() {
            let Some(w) = word(raw) else { continue };
            let bad = |what: &str| {
                parse_err(
                    path,
                    format!(
                        "line {}: {what}: {:?}",
                        ln + 1,
                        String::from_utf8_lossy(&raw[..raw.len().min(120)]).trim()
                    ),
                )
            };
            let line = std::str::from_utf8(raw).map_err(|_| bad("not UTF-8 text"))?;
            let mut tok = line.split_whitespace();
            tok.next();
            if w == b'v' {
                let mut c = [0.0; 3];
                for x in c.iter_mut() {
                    *x = tok
                        .next()
                        .ok_or_else(|| bad("a vertex needs three finite coordinates"))?
                        .parse::<f64>()
                        .map_err(|_| bad("bad vertex coordinate"))?;
                }
                if !c.iter().all(|x| x.is_finite()) {
                    return Err(bad("a vertex needs three finite coordinates"));
                }
                m.vertices.push(P3::new(c[0], c[1], c[2]));
                continue;
            }
            let n = m.vertices.len() as i64;
            let mut idx = [0u32; ply::MAX_CORNERS];
            let mut k = 0;
            for t in tok {
                if k == ply::MAX_CORNERS {
                    return Err(bad(&format!(
                        "a face of more than {} corners",
                        ply::MAX_CORNERS
                    )));
                }
                let v: i64 = t
                    .split('/')
                    .next()
                    .unwrap_or("")
                    .parse()
                    .map_err(|_| bad("bad face index"))?;
                let i = if v > 0 { v - 1 } else { n + v };
                if v == 0 || i < 0 || i >= n {
                    return Err(bad(&format!("face index {v} with {n} vertices so far")));
                }
                idx[k] = i as u32;
                k += 1;
            }
            if k < 3 {
                return Err(bad("a face needs at least three vertices"));
            }
            if (1..k).any(|a| idx[..a].contains(&idx[a])) {
                return Err(bad("a face visits one vertex twice"));
            }
            if m.triangles.len() + k - 2 > cap {
                return Err(bad(&format!(
                    "more than {MAX_TRIANGLES_PER_VERTEX} triangles per vertex ({nv} vertices): \
                     not a surface"
                )));
            }
            if m.triangles.len() + k - 2 > m.triangles.capacity() {
                return Err(bad("more triangles than the faces' text allows"));
            }
            for j in 1..k - 1 {
                m.triangles.push([idx[0], idx[j], idx[j + 1]]);
            }
        }
        Ok(m)
    }

    /// Parses PLY (ascii, binary_little_endian or binary_big_endian): the x, y, z properties
    /// of `vertex` and the index list of `face` (vertex_indices or vertex_index); faces with
    /// more than three corners are fan-triangulated; other elements and properties skipped.
    pub fn parse_ply(bytes: &[u8], path: &Path) -> Result<TriMesh, MeshError> {
        ply::parse(bytes, path)
    }
}

/// The most triangles an OBJ file may make per vertex it lists.
const MAX_TRIANGLES_PER_VERTEX: usize = 8;

fn check_finite_soup(soup: &[[P3; 3]], path: &Path) -> Result<(), MeshError> {
    if let Some(t) = soup
        .iter()
        .position(|t| t.iter().any(|p| !p.iter().all(|c| c.is_finite())))
    {
        return Err(parse_err(
            path,
            format!("facet {t} has a non-finite coordinate"),
        ));
    }
    Ok(())
}

mod ply {
    use super::{parse_err, MeshError, TriMesh, P3};
    use std::path::Path;

    #[derive(Clone, Copy, PartialEq)]
    enum Scalar {
        I8,
        U8,
        I16,
        U16,
        I32,
        U32,
        F32,
        F64,
    }

    impl Scalar {
        fn parse(s: &str) -> Option<Scalar> {
            Some(match s {
                "char" | "int8" => Scalar::I8,
                "uchar" | "uint8" => Scalar::U8,
                "short" | "int16" => Scalar::I16,
                "ushort" | "uint16" => Scalar::U16,
                "int" | "int32" => Scalar::I32,
                "uint" | "uint32" => Scalar::U32,
                "float" | "float32" => Scalar::F32,
                "double" | "float64" => Scalar::F64,
                _ => return None,
            })
        }
        fn size(self) -> usize {
            match self {
                Scalar::I8 | Scalar::U8 => 1,
                Scalar::I16 | Scalar::U16 => 2,
                Scalar::I32 | Scalar::U32 | Scalar::F32 => 4,
                Scalar::F64 => 8,
            }
        }
    }

    struct Prop {
        name: String,
        /// Some(count type) for a list property.
        list: Option<Scalar>,
        ty: Scalar,
    }

    struct Element {
        name: String,
        count: usize,
        props: Vec<Prop>,
    }

    #[derive(PartialEq, Clone, Copy)]
    enum Enc {
        Ascii,
        Le,
        Be,
    }

    /// Reads values one at a time from the body.
    struct Body<'a> {
        enc: Enc,
        bytes: &'a [u8],
        pos: usize,
        tokens: std::str::SplitAsciiWhitespace<'a>,
    }

    impl Body<'_> {
        fn value(&mut self, ty: Scalar) -> Option<f64> {
            if self.enc == Enc::Ascii {
                return self.tokens.next()?.parse().ok();
            }
            let n = ty.size();
            let b = self.bytes.get(self.pos..self.pos + n)?;
            self.pos += n;
            let le = self.enc == Enc::Le;
            macro_rules! num {
                ($t:ty) => {{
                    let a = b.try_into().ok()?;
                    (if le {
                        <$t>::from_le_bytes(a)
                    } else {
                        <$t>::from_be_bytes(a)
                    }) as f64
                }};
            }
            Some(match ty {
                Scalar::I8 => b[0] as i8 as f64,
                Scalar::U8 => b[0] as f64,
                Scalar::I16 => num!(i16),
                Scalar::U16 => num!(u16),
                Scalar::I32 => num!(i32),
                Scalar::U32 => num!(u32),
                Scalar::F32 => num!(f32),
                Scalar::F64 => num!(f64),
            })
        }
    }

    pub fn parse(bytes: &[u8], path: &Path) -> Result<TriMesh, MeshError> {
        let end = bytes
            .windows(10)
            .position(|w| w == b"end_header")
            .ok_or_else(|| parse_err(path, "not a PLY file: no 'end_header'"))?;
        let mut body_start = end + 10;
        // The header ends with a line break (LF or CRLF).
        if bytes.get(body_start) == Some(&b'\r') {
            body_start += 1;
        }
        if bytes.get(body_start) == Some(&b'\n') {
            body_start += 1;
        }
        let header = std::str::from_utf8(&bytes[..end])
            .map_err(|_| parse_err(path, "PLY header is not ASCII text"))?;
        let mut lines = header.lines();
        if lines.next().map(str::trim) != Some("ply") {
            return Err(parse_err(path, "not a PLY file: first line is not 'ply'"));
        }
        let mut enc = None;
        let mut elems: Vec<Element> = Vec::new();
        for line in lines {
            let t: Vec<&str> = line.split_whitespace().collect();
            let bad = || parse_err(path, format!("bad PLY header line {:?}", line.trim()));
            match t.first().copied() {
                Some("format") => {
                    enc = Some(match t.get(1).copied() {
                        Some("ascii") => Enc::Ascii,
                        Some("binary_little_endian") => Enc::Le,
                        Some("binary_big_endian") => Enc::Be,
                        _ => return Err(bad()),
                    })
                }
                Some("element") => {
                    let count = t.get(2).and_then(|c| c.parse().ok()).ok_or_else(bad)?;
                    elems.push(Element {
                        name: t.get(1).ok_or_else(bad)?.to_string(),
                        count,
                        props: Vec::new(),
                    })
                }
                Some("property") => {
                    let e = elems.last_mut().ok_or_else(bad)?;
                    if t.get(1) == Some(&"list") {
                        if t.len() != 5 {
                            return Err(bad());
                        }
                        e.props.push(Prop {
                            name: t[4].to_string(),
                            list: Some(Scalar::parse(t[2]).ok_or_else(bad)?),
                            ty: Scalar::parse(t[3]).ok_or_else(bad)?,
                        });
                    } else {
                        if t.len() != 3 {
                            return Err(bad());
                        }
                        e.props.push(Prop {
                            name: t[2].to_string(),
                            list: None,
                            ty: Scalar::parse(t[1]).ok_or_else(bad)?,
                        });
                    }
                }
                _ => {}
            }
        }
        let enc = enc.ok_or_else(|| parse_err(path, "PLY header has no 'format' line"))?;
        let rest = &bytes[body_start..];
        let text = if enc == Enc::Ascii {
            std::str::from_utf8(rest).map_err(|_| parse_err(path, "ASCII PLY body is not text"))?
        } else {
            ""
        };
        let mut body = Body {
            enc,
            bytes: rest,
            pos: 0,
            tokens: text.split_ascii_whitespace(),
        };
        let mut m = TriMesh::default();
        // Allocation follows the body's size, whatever the header says: a triangle (12
        // bytes held) per 5 body bytes at most, which every real mesh meets (a triangle of
        // int indices takes 13 bytes, and its vertices take more), and vertices only as
        // many as the body can hold.
        let max_triangles = rest.len() / 5 + 64;
        for e in &elems {
            let pos_of = |n: &str| e.props.iter().position(|p| p.name == n && p.list.is_none());
            let xyz = [pos_of("x"), pos_of("y"), pos_of("z")];
            // The least a record of the element takes: each property's size (binary), or
            // a digit and a separator (ASCII). A count beyond what the rest of the body can
            // hold is refused before the loop: records of no property take no byte, and a
            // header's 499999999999 of them spun the reader for hours (cargo-fuzz, issue 37).
            let least: usize = e
                .props
                .iter()
                .map(|p| match (enc, p.list) {
                    (Enc::Ascii, _) => 2,
                    (_, Some(ct)) => ct.size(),
                    (_, None) => p.ty.size(),
                })
                .sum::<usize>()
                .max(1);
            let room = rest.len().saturating_sub(body.pos) / least;
            if e.count > room {
                return Err(parse_err(
                    path,
                    format!(
                        "PLY header says {} {} records; the {}-byte body holds at most {room}",
                        e.count,
                        e.name,
                        rest.len()
                    ),
                ));
            }
            if e.name == "vertex" {
                if let Some(p) = xyz
                    .iter()
                    .flatten()
                    .map(|&i| &e.props[i])
                    .find(|p| p.ty.size() < 2)
                {
                    return Err(parse_err(
                        path,
                        format!(
                            "PLY vertex property {} is 8-bit: 256 steps cannot describe a foot \
                             or a last (use float)",
                            p.name
                        ),
                    ));
                }
                m.vertices.reserve_exact(e.count);
            }
            let face_list = e.props.iter().position(|p| {
                p.list.is_some() && (p.name == "vertex_indices" || p.name == "vertex_index")
            });
            for k in 0..e.count {
                let short = || {
                    parse_err(
                        path,
                        format!("PLY body ends or is malformed in {} {k}", e.name),
                    )
                };
                let mut c = [0.0; 3];
                for (pi, p) in e.props.iter().enumerate() {
                    if let Some(ct) = p.list {
                        let n = body.value(ct).ok_or_else(short)?;
                        // Each entry takes at least one byte of what is left: a count beyond
                        // that (4294967295, 1e300) is refused before anything is reserved.
                        let left = rest.len().saturating_sub(body.pos);
                        if !(n >= 0.0 && n.fract() == 0.0 && n <= left as f64) {
                            return Err(parse_err(
                                path,
                                format!(
                                    "PLY {} {k}: a list of {n} entries, but {left} bytes are left",
                                    e.name
                                ),
                            ));
                        }
                        let n = n as usize;
                        let is_face = e.name == "face" && Some(pi) == face_list;
                        if !is_face {
                            // Another list (texture coordinates, ...): read past it.
                            for _ in 0..n {
                                body.value(p.ty).ok_or_else(short)?;
                            }
                            continue;
                        }
                        if !(3..=MAX_CORNERS).contains(&n) {
                            return Err(parse_err(
                                path,
                                format!(
                                    "PLY face {k} has {n} vertices; a face has 3 to {MAX_CORNERS}"
                                ),
                            ));
                        }
                        let nv = e_vertex_count(&elems);
                        let mut ids = [0u32; MAX_CORNERS];
                        for id in ids.iter_mut().take(n) {
                            let i = body.value(p.ty).ok_or_else(short)?;
                            if i < 0.0 || i >= nv as f64 || i.fract() != 0.0 {
                                return Err(parse_err(
                                    path,
                                    format!("PLY face {k} refers to vertex {i} of {nv}"),
                                ));
                            }
                            *id = i as u32;
                        }
                        if m.triangles.len() + n - 2 > max_triangles {
                            return Err(parse_err(
                                path,
                                format!(
                                    "PLY faces make more than {max_triangles} triangles from a \
                                     {}-byte body: more than a mesh of that size holds",
                                    rest.len()
                                ),
                            ));
                        }
                        grow_capped(&mut m.triangles, n - 2, max_triangles);
                        for j in 1..n - 1 {
                            m.triangles.push([ids[0], ids[j], ids[j + 1]]);
                        }
                    } else {
                        let v = body.value(p.ty).ok_or_else(short)?;
                        if let Some(a) = xyz.iter().position(|&q| q == Some(pi)) {
                            c[a] = v;
                        }
                    }
                }
                if e.name == "vertex" {
                    if xyz.iter().any(|q| q.is_none()) {
                        return Err(parse_err(path, "PLY vertex element lacks x, y or z"));
                    }
                    if !c.iter().all(|v| v.is_finite()) {
                        return Err(parse_err(path, format!("PLY vertex {k} is not finite")));
                    }
                    m.vertices.push(P3::new(c[0], c[1], c[2]));
                }
            }
        }
        Ok(m)
    }

    /// Corners of one face, at most: a fan of more is not a mesh of a foot or a last.
    pub(super) const MAX_CORNERS: usize = 256;

    /// Room for `more` items in `v`, doubling its capacity as `push` would but never past
    /// `cap` (what the input's size allows).
    pub(super) fn grow_capped<T>(v: &mut Vec<T>, more: usize, cap: usize) {
        let need = v.len() + more;
        if need > v.capacity() {
            let want = (v.capacity() * 2).max(need).max(64).min(cap.max(need));
            v.reserve_exact(want - v.len());
        }
    }

    fn e_vertex_count(elems: &[Element]) -> usize {
        elems
            .iter()
            .find(|e| e.name == "vertex")
            .map_or(0, |e| e.count)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    fn cuboid(a: P3, b: P3) -> TriMesh {
        TriMesh::cuboid(a, b)
    }

    #[test]
    fn formats_round_trip_and_detect() {
        let m = cuboid(P3::new(0.1, -2.5, 3.0), P3::new(1.7, 5.0, 7.25));
        let p = Path::new("mem.stl");
        let (a, k) = TriMesh::parse_stl(m.to_stl_ascii("x").as_bytes(), p).unwrap();
        assert_eq!(k, StlKind::Ascii);
        // STL has no shared vertices: the same corners per triangle, vertices renumbered.
        assert_eq!(a.triangles.len(), m.triangles.len());
        for t in 0..m.triangles.len() {
            assert_eq!(a.corners(t), m.corners(t));
        }
        let (b, k) = TriMesh::parse_stl(&m.to_stl_binary(), p).unwrap();
        assert_eq!(k, StlKind::Binary);
        for t in 0..m.triangles.len() {
            for (x, y) in b.corners(t).iter().zip(m.corners(t)) {
                assert!((x - y).norm() < 1e-6);
            }
        }
        for bin in [false, true] {
            assert_eq!(TriMesh::parse_ply(&m.to_ply(bin), p).unwrap(), m);
        }
        assert_eq!(TriMesh::parse_obj(m.to_obj().as_bytes(), p).unwrap(), m);
    }

    #[test]
    fn obj_polygons_and_negative_indices() {
        let src = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nf 1/1 2/1 3/1 4/1\nf -4 -2 -1\n";
        let m = TriMesh::parse_obj(src.as_bytes(), Path::new("q.obj")).unwrap();
        assert_eq!(m.triangles, vec![[0, 1, 2], [0, 2, 3], [0, 2, 3]]);
        let e = TriMesh::parse_obj(b"v 0 0 0\nf 1 2 3\n", Path::new("bad.obj")).unwrap_err();
        assert!(
            e.to_string().contains("bad.obj") && e.to_string().contains("line 2"),
            "{e}"
        );
    }

    #[test]
    fn ply_with_extra_properties_big_endian_and_quads() {
        let mut b = b"ply\r\nformat binary_big_endian 1.0\r\nelement vertex 4\r\nproperty float x\r\nproperty float y\r\n\
property float z\r\nproperty uchar red\r\nelement face 1\r\nproperty list uchar uint vertex_index\r\nend_header\r\n"
            .to_vec();
        for (x, y) in [(0.0f32, 0.0f32), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)] {
            for c in [x, y, 2.0] {
                b.extend_from_slice(&c.to_be_bytes());
            }
            b.push(255);
        }
        b.push(4);
        for i in [0u32, 1, 2, 3] {
            b.extend_from_slice(&i.to_be_bytes());
        }
        let m = TriMesh::parse_ply(&b, Path::new("q.ply")).unwrap();
        assert_eq!(m.vertices[2], P3::new(1.0, 1.0, 2.0));
        assert_eq!(m.triangles, vec![[0, 1, 2], [0, 2, 3]]);
        b.pop();
        assert!(TriMesh::parse_ply(&b, Path::new("q.ply")).is_err());
    }

    #[test]
    fn garbage_is_named() {
        let e = TriMesh::parse_stl(&[0u8, 159, 146, 150], Path::new("x.stl")).unwrap_err();
        assert!(e.to_string().starts_with("x.stl: not an STL file"), "{e}");
        let e = TriMesh::read("/nonexistent/y.stl").unwrap_err();
        assert!(e.to_string().contains("/nonexistent/y.stl"));
        assert!(matches!(
            TriMesh::read("z.xyz"),
            Err(MeshError::UnknownFormat { .. })
        ));
    }
}
