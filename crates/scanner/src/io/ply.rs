use footscan_geom::P3;
use std::path::Path;

/// Write a binary little-endian PLY point cloud (x, y, z in mm as float, plus a per-point
/// `quality` float), the layout MeshLab, CloudCompare and most CAD tools open.
pub fn write_ply_points(path: &Path, points: &[P3], quality: &[f32]) -> std::io::Result<()> {
    assert_eq!(points.len(), quality.len(), "one quality per point");
    super::write_atomic_with(path, |w| {
        write!(
            w,
            "ply\nformat binary_little_endian 1.0\ncomment footscan point cloud, units mm\n\
             element vertex {}\nproperty float x\nproperty float y\nproperty float z\n\
             property float quality\nend_header\n",
            points.len()
        )?;
        // One write of the whole body: four writes a point through the writer were 1 M
        // calls on a scan's points.
        let mut body = Vec::with_capacity(points.len() * 16);
        for (p, q) in points.iter().zip(quality) {
            for v in p.iter() {
                body.extend_from_slice(&(*v as f32).to_le_bytes());
            }
            body.extend_from_slice(&q.to_le_bytes());
        }
        w.write_all(&body)
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn header_and_body_sizes() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("p.ply");
        let pts = [P3::new(1.0, 2.0, 3.0), P3::new(4.0, 5.0, 6.5)];
        write_ply_points(&p, &pts, &[0.5, 1.0]).unwrap();
        let bytes = std::fs::read(&p).unwrap();
        let end = b"end_header\n";
        let at = bytes.windows(end.len()).position(|w| w == end).unwrap() + end.len();
        let header = std::str::from_utf8(&bytes[..at]).unwrap();
        assert!(header.contains("element vertex 2"));
        assert_eq!(bytes.len() - at, 2 * 16);
        let z1 = f32::from_le_bytes(bytes[at + 24..at + 28].try_into().unwrap());
        assert_eq!(z1, 6.5);
    }
}
