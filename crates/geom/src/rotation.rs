//! The scanner world's one Euler-angle convention: R = Rz(rz) Ry(ry) Rx(rx), angles in
//! degrees. The simulated camera's tilt and a calibration board's pose are both given in it,
//! so it lives below both.

/// R = Rz(rz) * Ry(ry) * Rx(rx), angles in degrees.
pub fn rotation_zyx_deg(t: [f64; 3]) -> [[f64; 3]; 3] {
    let (sx, cx) = t[0].to_radians().sin_cos();
    let (sy, cy) = t[1].to_radians().sin_cos();
    let (sz, cz) = t[2].to_radians().sin_cos();
    let rx = [[1.0, 0.0, 0.0], [0.0, cx, -sx], [0.0, sx, cx]];
    let ry = [[cy, 0.0, sy], [0.0, 1.0, 0.0], [-sy, 0.0, cy]];
    let rz = [[cz, -sz, 0.0], [sz, cz, 0.0], [0.0, 0.0, 1.0]];
    matmul(&matmul(&rz, &ry), &rx)
}

fn matmul(a: &[[f64; 3]; 3], b: &[[f64; 3]; 3]) -> [[f64; 3]; 3] {
    let mut m = [[0.0; 3]; 3];
    for (i, row) in m.iter_mut().enumerate() {
        for (j, v) in row.iter_mut().enumerate() {
            *v = (0..3).map(|k| a[i][k] * b[k][j]).sum();
        }
    }
    m
}
