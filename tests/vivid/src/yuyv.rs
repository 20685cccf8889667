//! YUYV frames for the loop, from RGB24 (the encoder the driver's decoder is tested against).

/// BT.601 limited-range YUYV of a packed RGB24 image (`w` even): Y per pixel, U and V from the
/// pair's mean.
pub fn from_rgb(rgb: &[u8], w: usize, h: usize) -> Vec<u8> {
    let mut out = vec![0u8; w * h * 2];
    let y = |p: &[u8]| {
        let (r, g, b) = (p[0] as i32, p[1] as i32, p[2] as i32);
        (16 + ((66 * r + 129 * g + 25 * b + 128) >> 8)).clamp(0, 255) as u8
    };
    for (i, pair) in rgb.chunks_exact(6).enumerate() {
        let (a, b) = (&pair[..3], &pair[3..]);
        let m = |k: usize| (a[k] as i32 + b[k] as i32) / 2;
        let (r, g, bl) = (m(0), m(1), m(2));
        let u = (128 + ((-38 * r - 74 * g + 112 * bl + 128) >> 8)).clamp(0, 255) as u8;
        let v = (128 + ((112 * r - 94 * g - 18 * bl + 128) >> 8)).clamp(0, 255) as u8;
        out[4 * i..4 * i + 4].copy_from_slice(&[y(a), u, y(b), v]);
    }
    out
}
