//! A frame id written into the first rows of a frame, so each captured frame can be matched
//! with the output frame it came from (vivid's loop repeats and skips frames).
//!
//! 64 blocks across rows `0..ID_ROWS`: the 32 bits of the id, then the 32 bits of
//! `id ^ CHECK`; a block is 255 for a one, 0 for a zero. A frame whose code does not check
//! (vivid's test pattern, a frame from before the loop engaged) has no id.

/// Rows holding the code; the detector's accuracy is evaluated below them.
pub const ID_ROWS: usize = 4;
const CHECK: u32 = 0x5A3C_96E1;
const BLOCKS: usize = 64;

fn bits(id: u32) -> u64 {
    ((id as u64) << 32) | (id ^ CHECK) as u64
}

/// Write `id` into rows `0..ID_ROWS` of a `width`-wide Gray8 image.
pub fn write_id(px: &mut [u8], width: usize, id: u32) {
    let bw = width / BLOCKS;
    assert!(bw >= 4, "image too narrow for the id code");
    let b = bits(id);
    for r in 0..ID_ROWS {
        let row = &mut px[r * width..(r + 1) * width];
        row.fill(0);
        for k in 0..BLOCKS {
            if b >> (63 - k) & 1 == 1 {
                row[k * bw..(k + 1) * bw].fill(255);
            }
        }
    }
}

/// Write `id` into rows `0..ID_ROWS` of a packed `width`-wide RGB24 image in pure red (a one
/// is R 255, G = B = 0): it survives a red-minus-others channel as 255.
pub fn write_id_rgb(px: &mut [u8], width: usize, id: u32) {
    let mut grey = vec![0u8; ID_ROWS * width];
    write_id(&mut grey, width, id);
    for (i, &v) in grey.iter().enumerate() {
        px[3 * i..3 * i + 3].copy_from_slice(&[v, 0, 0]);
    }
}

/// Write `id` into rows `0..ID_ROWS` of a packed `width`-wide YUYV image, the RGB24 code
/// encoded as [`crate::yuyv::from_rgb`] does (blocks start on even columns, so no pixel
/// pair straddles two blocks).
pub fn write_id_yuyv(px: &mut [u8], width: usize, id: u32) {
    let mut rgb = vec![0u8; ID_ROWS * width * 3];
    write_id_rgb(&mut rgb, width, id);
    let yuyv = crate::yuyv::from_rgb(&rgb, width, ID_ROWS);
    px[..yuyv.len()].copy_from_slice(&yuyv);
}

/// The id in rows `0..ID_ROWS`, if the code is intact.
pub fn read_id(px: &[u8], width: usize) -> Option<u32> {
    let bw = width / BLOCKS;
    if bw < 4 || px.len() < ID_ROWS * width {
        return None;
    }
    let mut b = 0u64;
    for k in 0..BLOCKS {
        // Inner pixels of the block in the inner rows.
        let mut sum = 0u32;
        let mut n = 0u32;
        for r in 1..ID_ROWS - 1 {
            for c in k * bw + 1..(k + 1) * bw - 1 {
                sum += px[r * width + c] as u32;
                n += 1;
            }
        }
        let mean = sum / n;
        let bit = match mean {
            0..=40 => 0,
            215..=255 => 1,
            _ => return None,
        };
        b = (b << 1) | bit;
    }
    let id = (b >> 32) as u32;
    ((b as u32) == id ^ CHECK).then_some(id)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trip() {
        let w = 640;
        let mut px = vec![77u8; w * 10];
        for id in [0, 1, 12345, u32::MAX] {
            write_id(&mut px, w, id);
            assert_eq!(read_id(&px, w), Some(id));
            // Rows below are untouched.
            assert!(px[ID_ROWS * w..].iter().all(|&p| p == 77));
        }
    }

    #[test]
    fn damaged_or_absent_codes_are_rejected() {
        let w = 1280;
        let mut px = vec![0u8; w * 8];
        write_id(&mut px, w, 42);
        // Flip one block: the check fails.
        let bw = w / 64;
        for r in 0..ID_ROWS {
            for c in 0..bw {
                px[r * w + c] ^= 255;
            }
        }
        assert_eq!(read_id(&px, w), None);
        // A gray test pattern has no code.
        assert_eq!(read_id(&vec![128u8; w * 8], w), None);
        // All black would be id 0 with check 0, which fails.
        assert_eq!(read_id(&vec![0u8; w * 8], w), None);
    }
}
