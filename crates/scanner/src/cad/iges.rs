//! The solid as an IGES 5.3 file: a manifold solid B-rep object (entity 186) of one closed shell
//! (514, form 1) of faces (510) on planes (190, with a 116 point and a 123 normal), each bounded
//! by one loop (508) of edges from one edge list (504) of lines (110) between the vertices of
//! one vertex list (502). Millimetres. The faces are those of the STEP file ([`super::step`]).

use super::step::facets;
use crate::surface::solid::OutlineSolid;
use footscan_geom::export::real;
use std::collections::HashMap;
use std::path::Path;

/// Writes `solid` to `path` as an IGES BREP solid, atomically; returns the face count.
pub fn write_iges_solid(path: &Path, solid: &OutlineSolid, name: &str) -> std::io::Result<usize> {
    let (text, faces) = iges_solid(solid, name);
    crate::io::write_atomic(path, text.as_bytes())?;
    Ok(faces)
}

struct Entity {
    kind: u32,
    form: u32,
    params: Vec<String>,
    /// Physically dependent (a part of the solid, not shown alone).
    dependent: bool,
}

/// The IGES text of `solid` and its number of faces.
pub fn iges_solid(solid: &OutlineSolid, name: &str) -> (String, usize) {
    let faces = facets(solid);
    let mut ents: Vec<Entity> = Vec::new();
    // DE pointer of entity k (0-based): 2 k + 1.
    let de = |k: usize| (2 * k + 1).to_string();
    // Vertices used, in one list.
    let mut vindex: HashMap<u32, usize> = HashMap::new();
    let mut vlist: Vec<u32> = Vec::new();
    for f in &faces {
        for &v in &f.ids {
            vindex.entry(v).or_insert_with(|| {
                vlist.push(v);
                vlist.len()
            });
        }
    }
    // Edges: each unordered pair once, directed from its first use.
    let mut eindex: HashMap<(u32, u32), usize> = HashMap::new();
    let mut elist: Vec<(u32, u32)> = Vec::new();
    for f in &faces {
        let n = f.ids.len();
        for k in 0..n {
            let (a, b) = (f.ids[k], f.ids[(k + 1) % n]);
            if !eindex.contains_key(&(a, b)) && !eindex.contains_key(&(b, a)) {
                elist.push((a, b));
                eindex.insert((a, b), elist.len());
            }
        }
    }
    let p = |v: u32| solid.vertices[v as usize];
    // 0: vertex list.
    let mut params = vec![vlist.len().to_string()];
    for &v in &vlist {
        params.extend(p(v).iter().map(|&c| real(c)));
    }
    ents.push(Entity {
        kind: 502,
        form: 1,
        params,
        dependent: true,
    });
    let vlist_de = de(0);
    // Lines, then the edge list.
    let line0 = ents.len();
    for &(a, b) in &elist {
        let mut params: Vec<String> = p(a).iter().map(|&c| real(c)).collect();
        params.extend(p(b).iter().map(|&c| real(c)));
        ents.push(Entity {
            kind: 110,
            form: 0,
            params,
            dependent: true,
        });
    }
    let mut params = vec![elist.len().to_string()];
    for (k, &(a, b)) in elist.iter().enumerate() {
        params.push(de(line0 + k));
        params.push(vlist_de.clone());
        params.push(vindex[&a].to_string());
        params.push(vlist_de.clone());
        params.push(vindex[&b].to_string());
    }
    let elist_k = ents.len();
    ents.push(Entity {
        kind: 504,
        form: 1,
        params,
        dependent: true,
    });
    // Faces: point, normal, plane, loop, face.
    let mut face_des = Vec::new();
    for f in &faces {
        let o = p(f.ids[0]);
        let pk = ents.len();
        ents.push(Entity {
            kind: 116,
            form: 0,
            params: vec![real(o[0]), real(o[1]), real(o[2]), "0".into()],
            dependent: true,
        });
        let nk = ents.len();
        ents.push(Entity {
            kind: 123,
            form: 0,
            params: f.normal.iter().map(|&c| real(c)).collect(),
            dependent: true,
        });
        let sk = ents.len();
        ents.push(Entity {
            kind: 190,
            form: 0,
            params: vec![de(pk), de(nk)],
            dependent: true,
        });
        let n = f.ids.len();
        let mut lp = vec![n.to_string()];
        for k in 0..n {
            let (a, b) = (f.ids[k], f.ids[(k + 1) % n]);
            let (idx, same) = match eindex.get(&(a, b)) {
                Some(&i) => (i, 1),
                None => (eindex[&(b, a)], 0),
            };
            lp.extend([
                "0".into(),
                de(elist_k),
                idx.to_string(),
                same.to_string(),
                "0".into(),
            ]);
        }
        let lk = ents.len();
        ents.push(Entity {
            kind: 508,
            form: 1,
            params: lp,
            dependent: true,
        });
        let fk = ents.len();
        ents.push(Entity {
            kind: 510,
            form: 1,
            params: vec![de(sk), "1".into(), "1".into(), de(lk)],
            dependent: true,
        });
        face_des.push(de(fk));
    }
    let mut params = vec![face_des.len().to_string()];
    for d in &face_des {
        params.push(d.clone());
        params.push("1".into());
    }
    let shell_k = ents.len();
    ents.push(Entity {
        kind: 514,
        form: 1,
        params,
        dependent: true,
    });
    ents.push(Entity {
        kind: 186,
        form: 0,
        params: vec![de(shell_k), "1".into(), "0".into()],
        dependent: false,
    });

    // Sections.
    let mut out = String::new();
    let start = format!(
        "{}: a closed solid (manifold solid B-rep, entity 186), millimetres, foot frame",
        hollerith_free(name)
    );
    let mut s_lines = 0;
    for chunk in start.as_bytes().chunks(72) {
        s_lines += 1;
        out.push_str(&format!(
            "{:<72}S{:>7}\n",
            String::from_utf8_lossy(chunk),
            s_lines
        ));
    }
    let g = [
        "1H,".to_string(),
        "1H;".to_string(),
        hollerith(name),
        hollerith("model.igs"),
        hollerith("footscan"),
        hollerith(concat!("footscan ", env!("CARGO_PKG_VERSION"))),
        "32".into(),
        "38".into(),
        "6".into(),
        "308".into(),
        "15".into(),
        hollerith(name),
        "1.".into(),
        "2".into(),
        "2HMM".into(),
        "1".into(),
        "1.".into(),
        hollerith("20000101.000000"),
        "1.E-6".into(),
        "1000.".into(),
        hollerith("footscan"),
        hollerith(""),
        "11".into(),
        "0".into(),
    ];
    let g_lines = wrap_params(&g, ';', 72)
        .into_iter()
        .enumerate()
        .map(|(k, l)| format!("{l:<72}G{:>7}\n", k + 1))
        .collect::<Vec<_>>();
    for l in &g_lines {
        out.push_str(l);
    }
    // Parameter data first (to know each entity's first line and line count).
    let mut p_text = String::new();
    let mut p_at = Vec::with_capacity(ents.len());
    let mut p_line = 1;
    for (k, e) in ents.iter().enumerate() {
        let mut all = vec![e.kind.to_string()];
        all.extend(e.params.iter().cloned());
        let lines = wrap_params(&all, ';', 64);
        p_at.push((p_line, lines.len()));
        for l in lines {
            p_text.push_str(&format!("{l:<64} {:>7}P{:>7}\n", 2 * k + 1, p_line));
            p_line += 1;
        }
    }
    let mut d_text = String::new();
    for (k, e) in ents.iter().enumerate() {
        let (first, count) = p_at[k];
        let status = if e.dependent { "00010001" } else { "00000000" };
        let d1 = 2 * k + 1;
        d_text.push_str(&format!(
            "{:>8}{:>8}{:>8}{:>8}{:>8}{:>8}{:>8}{:>8}{:>8}D{:>7}\n",
            e.kind, first, 0, 0, 0, 0, 0, 0, status, d1
        ));
        d_text.push_str(&format!(
            "{:>8}{:>8}{:>8}{:>8}{:>8}{:>8}{:>8}{:>8}{:>8}D{:>7}\n",
            e.kind,
            0,
            0,
            count,
            e.form,
            "",
            "",
            "",
            0,
            d1 + 1
        ));
    }
    out.push_str(&d_text);
    out.push_str(&p_text);
    out.push_str(&format!(
        "{:<72}T{:>7}\n",
        format!(
            "S{:>7}G{:>7}D{:>7}P{:>7}",
            s_lines,
            g_lines.len(),
            2 * ents.len(),
            p_line - 1
        ),
        1
    ));
    (out, faces.len())
}

/// Parameters joined by ',' and ended by `end`, cut into lines of at most `width` characters
/// between parameters (a parameter longer than a line is not split: none here is).
fn wrap_params(params: &[String], end: char, width: usize) -> Vec<String> {
    let mut lines = Vec::new();
    let mut cur = String::new();
    for (k, p) in params.iter().enumerate() {
        let sep = if k + 1 == params.len() { end } else { ',' };
        let piece = format!("{p}{sep}");
        if !cur.is_empty() && cur.len() + piece.len() > width {
            lines.push(std::mem::take(&mut cur));
        }
        cur.push_str(&piece);
    }
    if !cur.is_empty() {
        lines.push(cur);
    }
    lines
}

fn hollerith_free(s: &str) -> String {
    s.chars().filter(|c| (' '..='~').contains(c)).collect()
}

fn hollerith(s: &str) -> String {
    let s = hollerith_free(s);
    if s.is_empty() {
        return String::new();
    }
    format!("{}H{s}", s.len())
}
