//! 3MF (the 3D Manufacturing Format, core specification 1.3): a ZIP package holding the
//! content types, the package relationship and one model part with the mesh in millimetres.
//!
//! The ZIP is written here with its entries stored (no compression): the `zip` crate is not
//! in this build's offline registry, and a stored ZIP is three small record kinds
//! (local header, central directory entry, end record) and a CRC-32 (crc32fast). 3MF readers
//! accept stored entries (the specification's OPC layer allows both methods).

use footscan_geom::mesh::TriMesh;
use std::fmt::Write as _;

const CONTENT_TYPES: &str = r#"<?xml version="1.0" encoding="UTF-8"?>
<Types xmlns="http://schemas.openxmlformats.org/package/2006/content-types">
 <Default Extension="rels" ContentType="application/vnd.openxmlformats-package.relationships+xml"/>
 <Default Extension="model" ContentType="application/vnd.ms-package.3dmanufacturing-3dmodel+xml"/>
</Types>
"#;

const RELS: &str = r#"<?xml version="1.0" encoding="UTF-8"?>
<Relationships xmlns="http://schemas.openxmlformats.org/package/2006/relationships">
 <Relationship Target="/3D/3dmodel.model" Id="rel0" Type="http://schemas.microsoft.com/3dmanufacturing/2013/01/3dmodel"/>
</Relationships>
"#;

/// The model part: one object of type "model" holding `mesh`, one build item.
pub fn model_xml(mesh: &TriMesh, name: &str) -> String {
    let mut s = String::with_capacity(64 * mesh.vertices.len() + 48 * mesh.triangles.len());
    s.push_str(
        "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n\
         <model unit=\"millimeter\" xml:lang=\"en-US\" \
         xmlns=\"http://schemas.microsoft.com/3dmanufacturing/core/2015/02\">\n",
    );
    let _ = writeln!(s, " <metadata name=\"Title\">{}</metadata>", escape(name));
    let _ = writeln!(s, " <metadata name=\"Application\">footscan</metadata>");
    s.push_str(" <resources>\n  <object id=\"1\" type=\"model\">\n   <mesh>\n    <vertices>\n");
    for v in &mesh.vertices {
        let _ = writeln!(
            s,
            "     <vertex x=\"{:.5}\" y=\"{:.5}\" z=\"{:.5}\"/>",
            v.x, v.y, v.z
        );
    }
    s.push_str("    </vertices>\n    <triangles>\n");
    for t in &mesh.triangles {
        let _ = writeln!(
            s,
            "     <triangle v1=\"{}\" v2=\"{}\" v3=\"{}\"/>",
            t[0], t[1], t[2]
        );
    }
    s.push_str(
        "    </triangles>\n   </mesh>\n  </object>\n </resources>\n \
         <build>\n  <item objectid=\"1\"/>\n </build>\n</model>\n",
    );
    s
}

fn escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

/// The 3MF package of `mesh` (millimetres) as bytes.
pub fn to_3mf(mesh: &TriMesh, name: &str) -> Vec<u8> {
    let model = model_xml(mesh, name);
    stored_zip(&[
        ("[Content_Types].xml", CONTENT_TYPES.as_bytes()),
        ("_rels/.rels", RELS.as_bytes()),
        ("3D/3dmodel.model", model.as_bytes()),
    ])
}

/// A ZIP archive of `files` (name, bytes), every entry stored. Sizes must fit 32 bits (a
/// 3MF of a 1 mm insole is a few MB).
pub fn stored_zip(files: &[(&str, &[u8])]) -> Vec<u8> {
    let mut out = Vec::new();
    let mut central = Vec::new();
    // 1980-01-01 00:00 in DOS time: the archive's bytes depend on nothing but the mesh.
    let (time, date) = (0u16, (1u16 << 5) | 1);
    for (name, data) in files {
        let crc = crc32fast::hash(data);
        let offset = out.len() as u32;
        let size = u32::try_from(data.len()).expect("a 3MF part under 4 GB");
        let header = |sig: u32, central: bool| {
            let mut h = Vec::new();
            h.extend(sig.to_le_bytes());
            if central {
                h.extend(20u16.to_le_bytes()); // made by: 2.0
            }
            h.extend(20u16.to_le_bytes()); // needed: 2.0
            h.extend(0u16.to_le_bytes()); // flags
            h.extend(0u16.to_le_bytes()); // method: stored
            h.extend(time.to_le_bytes());
            h.extend(date.to_le_bytes());
            h.extend(crc.to_le_bytes());
            h.extend(size.to_le_bytes());
            h.extend(size.to_le_bytes());
            h.extend((name.len() as u16).to_le_bytes());
            h.extend(0u16.to_le_bytes()); // extra length
            if central {
                h.extend(0u16.to_le_bytes()); // comment length
                h.extend(0u16.to_le_bytes()); // disk
                h.extend(0u16.to_le_bytes()); // internal attributes
                h.extend(0u32.to_le_bytes()); // external attributes
                h.extend(offset.to_le_bytes());
            }
            h.extend(name.as_bytes());
            h
        };
        out.extend(header(0x0403_4b50, false));
        out.extend_from_slice(data);
        central.extend(header(0x0201_4b50, true));
    }
    let cd_offset = out.len() as u32;
    let cd_size = central.len() as u32;
    out.extend(central);
    out.extend(0x0605_4b50u32.to_le_bytes());
    out.extend(0u16.to_le_bytes());
    out.extend(0u16.to_le_bytes());
    out.extend((files.len() as u16).to_le_bytes());
    out.extend((files.len() as u16).to_le_bytes());
    out.extend(cd_size.to_le_bytes());
    out.extend(cd_offset.to_le_bytes());
    out.extend(0u16.to_le_bytes());
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use footscan_geom::P3;

    #[test]
    fn a_cube_package_has_its_parts_and_crc() {
        let m = TriMesh::cuboid(P3::origin(), P3::new(1.0, 2.0, 3.0));
        let z = to_3mf(&m, "cube");
        assert_eq!(&z[..4], b"PK\x03\x04");
        let end = &z[z.len() - 22..];
        assert_eq!(&end[..4], b"PK\x05\x06");
        assert_eq!(u16::from_le_bytes([end[10], end[11]]), 3);
        let xml = model_xml(&m, "cube");
        assert_eq!(xml.matches("<vertex ").count(), 8);
        assert_eq!(xml.matches("<triangle ").count(), 12);
        assert!(xml.contains("unit=\"millimeter\""));
        // The model part is stored whole: its bytes appear in the archive as they are.
        let at = z
            .windows(xml.len())
            .position(|w| w == xml.as_bytes())
            .expect("stored part");
        let header = at - 30 - "3D/3dmodel.model".len();
        let crc = u32::from_le_bytes(z[header + 14..header + 18].try_into().unwrap());
        assert_eq!(crc, crc32fast::hash(xml.as_bytes()));
    }
}
