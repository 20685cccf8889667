/*
 * A per-scan footscan wasm stage (ABI 1, docs/plugins.md): the scan's points in, the extent
 * of the point set out as `key value` lines, which footscan adds to scan.json.
 *
 * Freestanding C (no libc, no WASI, no imports). Build with Debian's clang and lld:
 *
 *   clang --target=wasm32 -O2 -nostdlib -Wl,--no-entry -I.. -o extent.wasm extent.c
 *
 * Input: `len` bytes of points, x y z as little-endian f64 each (24 bytes a point, mm, the
 * foot frame). Output: points, x_min_mm, x_max_mm, length_mm (x), width_mm (y), z_max_mm.
 * examples/plugins/python/extent_stage.py is the same in numpy.
 */

#include "footscan_abi.h"

/* Append `s` to the report at *at (bounded by cap). */
static void put_str(char *out, int *at, int cap, const char *s) {
    while (*s && *at < cap) out[(*at)++] = *s++;
}

/* A number with 6 decimals: enough for a millimetre figure, exact enough to compare. */
static void put_num(char *out, int *at, int cap, double v) {
    char buf[48];
    int n = 0;
    if (v < 0) { put_str(out, at, cap, "-"); v = -v; }
    unsigned long long scaled = (unsigned long long)(v * 1e6 + 0.5);
    unsigned long long ip = scaled / 1000000ull, fp = scaled % 1000000ull;
    do { buf[n++] = (char)('0' + ip % 10); ip /= 10; } while (ip);
    while (n--) { char c[2] = {buf[n], 0}; put_str(out, at, cap, c); }
    put_str(out, at, cap, ".");
    for (unsigned long long d = 100000ull; d; d /= 10) {
        char c[2] = {(char)('0' + (fp / d) % 10), 0};
        put_str(out, at, cap, c);
    }
}

static void line(char *out, int *at, int cap, const char *key, double v) {
    put_str(out, at, cap, key);
    put_str(out, at, cap, " ");
    put_num(out, at, cap, v);
    put_str(out, at, cap, "\n");
}

/* Report length, or -1: the input is not whole points. */
EXPORT("footscan_scan") int footscan_scan(const double *pts, int len, char *out, int cap) {
    if (len % 24) return -1;
    int n = len / 24, at = 0;
    double x0 = 1e300, x1 = -1e300, y0 = 1e300, y1 = -1e300, z1 = -1e300;
    for (int i = 0; i < n; i++) {
        double x = pts[3 * i], y = pts[3 * i + 1], z = pts[3 * i + 2];
        if (x < x0) x0 = x;
        if (x > x1) x1 = x;
        if (y < y0) y0 = y;
        if (y > y1) y1 = y;
        if (z > z1) z1 = z;
    }
    line(out, &at, cap, "points", (double)n);
    if (n > 0) {
        line(out, &at, cap, "x_min_mm", x0);
        line(out, &at, cap, "x_max_mm", x1);
        line(out, &at, cap, "length_mm", x1 - x0);
        line(out, &at, cap, "width_mm", y1 - y0);
        line(out, &at, cap, "z_max_mm", z1);
    }
    return at;
}
