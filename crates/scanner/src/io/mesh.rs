//! Triangle meshes as binary STL, binary PLY and OBJ, written atomically. Coordinates are
//! stored as 32-bit floats in STL and PLY (what the formats and their readers expect; about
//! 3e-5 mm at 300 mm) and with 6 decimals in OBJ.

use crate::surface::Mesh;
use std::path::Path;

/// Binary STL: facet normals from the winding (counter-clockwise seen from outside).
pub fn write_stl(path: &Path, mesh: &Mesh) -> std::io::Result<()> {
    super::write_atomic_with(path, |w| {
        let mut header = [0u8; 80];
        let text = b"footscan plantar model (binary STL, mm)";
        header[..text.len()].copy_from_slice(text);
        w.write_all(&header)?;
        w.write_all(&(mesh.triangles.len() as u32).to_le_bytes())?;
        for (k, t) in mesh.triangles.iter().enumerate() {
            for c in mesh.face_normal(k) {
                w.write_all(&(c as f32).to_le_bytes())?;
            }
            for &i in t {
                for c in mesh.vertices[i as usize] {
                    w.write_all(&(c as f32).to_le_bytes())?;
                }
            }
            w.write_all(&[0, 0])?;
        }
        Ok(())
    })
}

/// Binary little-endian PLY with vertices and triangular faces.
pub fn write_ply_mesh(path: &Path, mesh: &Mesh) -> std::io::Result<()> {
    super::write_atomic_with(path, |w| {
        write!(
            w,
            "ply\nformat binary_little_endian 1.0\ncomment footscan plantar model, mm\n\
             element vertex {}\nproperty float x\nproperty float y\nproperty float z\n\
             element face {}\nproperty list uchar int vertex_indices\nend_header\n",
            mesh.vertices.len(),
            mesh.triangles.len()
        )?;
        for v in &mesh.vertices {
            for c in v {
                w.write_all(&(*c as f32).to_le_bytes())?;
            }
        }
        for t in &mesh.triangles {
            w.write_all(&[3])?;
            for &i in t {
                w.write_all(&(i as i32).to_le_bytes())?;
            }
        }
        Ok(())
    })
}

/// Wavefront OBJ (1-based indices).
pub fn write_obj(path: &Path, mesh: &Mesh) -> std::io::Result<()> {
    super::write_atomic_with(path, |w| {
        writeln!(w, "# footscan plantar model, mm")?;
        for v in &mesh.vertices {
            writeln!(w, "v {:.6} {:.6} {:.6}", v[0], v[1], v[2])?;
        }
        for t in &mesh.triangles {
            writeln!(w, "f {} {} {}", t[0] + 1, t[1] + 1, t[2] + 1)?;
        }
        Ok(())
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tetra() -> Mesh {
        Mesh {
            vertices: vec![
                [0.0, 0.0, 0.0],
                [1.0, 0.0, 0.0],
                [0.0, 1.0, 0.0],
                [0.0, 0.0, 1.0],
            ],
            triangles: vec![[0, 2, 1], [0, 1, 3], [1, 2, 3], [0, 3, 2]],
        }
    }

    #[test]
    fn formats_have_the_right_sizes_and_content() {
        let m = tetra();
        m.check_watertight().unwrap();
        assert!(m.signed_volume() > 0.0);
        let dir = tempfile::tempdir().unwrap();
        let stl = dir.path().join("m.stl");
        write_stl(&stl, &m).unwrap();
        let b = std::fs::read(&stl).unwrap();
        assert_eq!(b.len(), 84 + 50 * 4);
        assert_eq!(u32::from_le_bytes(b[80..84].try_into().unwrap()), 4);
        // First facet normal: (0, 0, -1).
        let nz = f32::from_le_bytes(b[92..96].try_into().unwrap());
        assert_eq!(nz, -1.0);
        let ply = dir.path().join("m.ply");
        write_ply_mesh(&ply, &m).unwrap();
        let b = std::fs::read(&ply).unwrap();
        let h = b"end_header\n";
        let at = b.windows(h.len()).position(|w| w == h).unwrap() + h.len();
        assert_eq!(b.len() - at, 4 * 12 + 4 * 13);
        let obj = dir.path().join("m.obj");
        write_obj(&obj, &m).unwrap();
        let s = std::fs::read_to_string(&obj).unwrap();
        assert_eq!(s.lines().filter(|l| l.starts_with("v ")).count(), 4);
        assert!(s.contains("\nf 1 3 2\n"));
    }
}
