/*
 * A centre-of-gravity laser-line detector as a footscan wasm stage (ABI 1, docs/plugins.md).
 *
 * Freestanding C: no libc, no WASI, no imports, so the host grants it nothing. Build with
 * Debian's clang and lld (`make` here, or examples/plugins/cog-wasm/build.sh):
 *
 *   clang --target=wasm32 -O2 -msimd128 -nostdlib -Wl,--no-entry -I.. -o cog.wasm cog.c
 *
 * -msimd128 lets the row's maximum be found 16 (8-bit) or 8 (16-bit) pixels at a time with
 * WebAssembly's 128-bit SIMD, which wasmtime compiles to SSE/NEON; without it the same C
 * runs one pixel at a time (4.5x the built-in's time instead of about 2x: docs/method.md
 * section 14d). The first maximum is the same either way.
 *
 * Per row it does what the built-in `detect.cog` does with a fixed threshold, the ambiguity
 * test off (ambiguity > 1) and specular spikes not skipped: the first maximum, its flat top,
 * the run above the threshold, the border test, the background beside the run, the width at
 * half height, the saturation test, the centre of gravity of (value - threshold) over the
 * run, then rows with no other line within 2 rows rejected as isolated. The arithmetic is the
 * built-in's, in the same order and precision, so the columns are equal bit for bit
 * (crates/scanner/tests/plugin_wasm.rs checks it on simulated frames).
 *
 * Parameters (the stage's `args` table): threshold (8-bit DN, required), max_saturated_px
 * (default 12).
 */

#include "footscan_abi.h"

enum { ACCEPTED = 0, BELOW_THRESHOLD = 1, SATURATED = 2, AMBIGUOUS = 3, BORDER = 4, ISOLATED = 5 };
#define NEAR_ROWS 2

/* One output record per row, 24 bytes, little-endian (the host reads exactly this layout). */
struct row_out {
    double col;
    float intensity;
    float width;
    float quality;
    u32 reject;
};

static float threshold_dn = -1.0f;
static u32 max_saturated_px = 12;

static int key_is(const u8 *k, int n, const char *s) {
    int i = 0;
    for (; i < n && s[i]; i++)
        if (k[i] != (u8)s[i]) return 0;
    return i == n && s[i] == 0;
}

/* 0: accepted; 1: unknown key; 2: value out of range. */
EXPORT("footscan_param") int footscan_param(const u8 *key, int len, double value) {
    if (key_is(key, len, "threshold")) {
        if (!(value > 0.0 && value < 255.0)) return 2;
        threshold_dn = (float)value;
        return 0;
    }
    if (key_is(key, len, "max_saturated_px")) {
        if (!(value >= 1.0 && value <= 1e9)) return 2;
        max_saturated_px = (u32)value;
        return 0;
    }
    return 1;
}

static float minf(float a, float b) { return b < a ? b : a; }
static float maxf(float a, float b) { return b > a ? b : a; }
static float clampf(float v, float lo, float hi) { return v < lo ? lo : (v > hi ? hi : v); }

static struct row_out rejected(u32 why, float intensity) {
    struct row_out o = {__builtin_nan(""), intensity, 0.0f, 0.0f, why};
    return o;
}

/* The first maximum of a row: its value in *v, its index returned (0 for an all-zero row). */
#ifdef __wasm_simd128__
#include <wasm_simd128.h>

static u32 argmax8(const u8 *row, u32 w, u8 *vout) {
    v128_t m = wasm_i8x16_splat(0), m1 = m, m2 = m, m3 = m;
    u32 i = 0;
    /* 64 bytes an iteration: the host's time limit checks at every loop header, and four
     * times fewer headers is most of the module's time (docs/method.md 14d.3). */
    for (; i + 64 <= w; i += 64) {
        m = wasm_u8x16_max(m, wasm_v128_load(row + i));
        m1 = wasm_u8x16_max(m1, wasm_v128_load(row + i + 16));
        m2 = wasm_u8x16_max(m2, wasm_v128_load(row + i + 32));
        m3 = wasm_u8x16_max(m3, wasm_v128_load(row + i + 48));
    }
    m = wasm_u8x16_max(wasm_u8x16_max(m, m1), wasm_u8x16_max(m2, m3));
    for (; i + 16 <= w; i += 16) m = wasm_u8x16_max(m, wasm_v128_load(row + i));
    u8 lanes[16];
    wasm_v128_store(lanes, m);
    u8 v = 0;
    for (int k = 0; k < 16; k++) v = lanes[k] > v ? lanes[k] : v;
    for (; i < w; i++) v = row[i] > v ? row[i] : v;
    *vout = v;
    if (v == 0) return 0;
    v128_t s = wasm_i8x16_splat((char)v);
    for (i = 0; i + 64 <= w; i += 64) {
        v128_t e = wasm_v128_or(
            wasm_v128_or(wasm_i8x16_eq(wasm_v128_load(row + i), s),
                         wasm_i8x16_eq(wasm_v128_load(row + i + 16), s)),
            wasm_v128_or(wasm_i8x16_eq(wasm_v128_load(row + i + 32), s),
                         wasm_i8x16_eq(wasm_v128_load(row + i + 48), s)));
        if (wasm_v128_any_true(e)) break;
    }
    for (; i + 16 <= w; i += 16) {
        int b = wasm_i8x16_bitmask(wasm_i8x16_eq(wasm_v128_load(row + i), s));
        if (b) return i + (u32)__builtin_ctz((unsigned)b);
    }
    for (; i < w; i++)
        if (row[i] == v) return i;
    return 0;
}

static u32 argmax16(const u16 *row, u32 w, u16 *vout) {
    v128_t m = wasm_i16x8_splat(0), m1 = m, m2 = m, m3 = m;
    u32 i = 0;
    for (; i + 32 <= w; i += 32) {
        m = wasm_u16x8_max(m, wasm_v128_load(row + i));
        m1 = wasm_u16x8_max(m1, wasm_v128_load(row + i + 8));
        m2 = wasm_u16x8_max(m2, wasm_v128_load(row + i + 16));
        m3 = wasm_u16x8_max(m3, wasm_v128_load(row + i + 24));
    }
    m = wasm_u16x8_max(wasm_u16x8_max(m, m1), wasm_u16x8_max(m2, m3));
    for (; i + 8 <= w; i += 8) m = wasm_u16x8_max(m, wasm_v128_load(row + i));
    u16 lanes[8];
    wasm_v128_store(lanes, m);
    u16 v = 0;
    for (int k = 0; k < 8; k++) v = lanes[k] > v ? lanes[k] : v;
    for (; i < w; i++) v = row[i] > v ? row[i] : v;
    *vout = v;
    if (v == 0) return 0;
    v128_t s = wasm_i16x8_splat((short)v);
    for (i = 0; i + 32 <= w; i += 32) {
        v128_t e = wasm_v128_or(
            wasm_v128_or(wasm_i16x8_eq(wasm_v128_load(row + i), s),
                         wasm_i16x8_eq(wasm_v128_load(row + i + 8), s)),
            wasm_v128_or(wasm_i16x8_eq(wasm_v128_load(row + i + 16), s),
                         wasm_i16x8_eq(wasm_v128_load(row + i + 24), s)));
        if (wasm_v128_any_true(e)) break;
    }
    for (; i + 8 <= w; i += 8) {
        int b = wasm_i16x8_bitmask(wasm_i16x8_eq(wasm_v128_load(row + i), s));
        if (b) return i + (u32)__builtin_ctz((unsigned)b);
    }
    for (; i < w; i++)
        if (row[i] == v) return i;
    return 0;
}
#else
#define ARGMAX_FN(NAME, T)                                                                     \
    static u32 NAME(const T *row, u32 w, T *vout) {                                           \
        T v = 0;                                                                              \
        u32 pos = 0;                                                                          \
        for (u32 i = 0; i < w; i++)                                                           \
            if (row[i] > v) { v = row[i]; pos = i; }                                          \
        *vout = v;                                                                            \
        return pos;                                                                           \
    }
ARGMAX_FN(argmax8, u8)
ARGMAX_FN(argmax16, u16)
#endif

/* One row of `w` pixels of type T, full scale FULL, cut at `thr` (frame units). */
#define ROW_FN(NAME, T, FULL, ARGMAX)                                                          \
    static struct row_out NAME(const T *row, u32 w, float thr) {                              \
        if (w < 3) return rejected(BORDER, 0.0f);                                             \
        T v = 0;                                                                              \
        u32 pos = ARGMAX(row, w, &v);                                                         \
        float top = (float)v;                                                                 \
        if (top <= thr) return rejected(BELOW_THRESHOLD, top);                                \
        u32 a = pos, b = pos;                                                                 \
        while (a > 0 && row[a - 1] == v) a--;                                                 \
        while (b + 1 < w && row[b + 1] == v) b++;                                             \
        u32 saturated = top >= (float)(FULL) ? b - a + 1 : 0;                                 \
        if (saturated > max_saturated_px) return rejected(SATURATED, top);                    \
        u32 lo = a, hi = b;                                                                   \
        while (lo > 0 && (float)row[lo - 1] > thr) lo--;                                      \
        while (hi + 1 < w && (float)row[hi + 1] > thr) hi++;                                  \
        if (lo == 0 || hi + 1 == w) return rejected(BORDER, top);                             \
        float bg = minf((float)row[lo - 1], (float)row[hi + 1]);                              \
        if (lo >= 2) bg = minf(bg, (float)row[lo - 2]);                                       \
        if (hi + 2 < w) bg = minf(bg, (float)row[hi + 2]);                                    \
        float half = bg + 0.5f * (top - bg);                                                  \
        u32 l = a;                                                                            \
        while (l > lo && (float)row[l - 1] >= half) l--;                                      \
        float v0 = (float)row[l - 1], v1 = (float)row[l];                                     \
        float xl = (float)(l - 1) + clampf((half - v0) / maxf(v1 - v0, 1e-6f), 0.0f, 1.0f);   \
        u32 r = b;                                                                            \
        while (r < hi && (float)row[r + 1] >= half) r++;                                      \
        v0 = (float)row[r];                                                                   \
        v1 = (float)row[r + 1];                                                               \
        float xr = (float)r + clampf((v0 - half) / maxf(v0 - v1, 1e-6f), 0.0f, 1.0f);         \
        float width = maxf(xr - xl, 0.5f);                                                    \
        double s = 0.0, sx = 0.0;                                                             \
        for (u32 i = lo; i <= hi; i++) {                                                      \
            double wgt = (double)((float)row[i] - thr);                                       \
            s += wgt;                                                                         \
            sx += wgt * (double)i;                                                            \
        }                                                                                     \
        if (s <= 0.0) return rejected(BELOW_THRESHOLD, top);                                  \
        float full = (float)(FULL);                                                           \
        float sig = clampf((top - thr) / maxf(0.5f * full - thr, 1.0f), 0.0f, 1.0f);          \
        float uniq = 1.0f; /* no second peak is looked for: the ambiguity test is off */      \
        float sat = saturated > 0 ? 0.5f : 1.0f;                                              \
        struct row_out o = {sx / s, top, width, sig * uniq * sat, ACCEPTED};                  \
        return o;                                                                             \
    }

ROW_FN(row8, u8, 255, argmax8)
ROW_FN(row16, u16, 65535, argmax16)

/* Rows with no other accepted row within NEAR_ROWS above or below are specks, not a line. */
static void reject_isolated(struct row_out *out, u32 n) {
    long last_valid = -1;
    for (u32 r = 0; r < n; r++) {
        if (out[r].reject != ACCEPTED) continue;
        int above = last_valid >= 0 && r - (u32)last_valid <= NEAR_ROWS;
        int below = 0;
        for (u32 k = r + 1; k < r + 1 + NEAR_ROWS && k < n; k++)
            if (out[k].reject == ACCEPTED) below = 1;
        last_valid = (long)r;
        if (!above && !below) out[r] = rejected(ISOLATED, out[r].intensity);
    }
}

/* Rows written (== height), or a negative error: -1 no threshold set, -2 bad pixel size. */
EXPORT("footscan_detect")
int footscan_detect(const u8 *px, int width, int height, int bytes_per_px, struct row_out *out) {
    if (threshold_dn <= 0.0f) return -1;
    u32 w = (u32)width, h = (u32)height;
    for (u32 r = 0; r < h; r++) {
        if (bytes_per_px == 1)
            out[r] = row8(px + (unsigned long)r * w, w, threshold_dn);
        else if (bytes_per_px == 2)
            out[r] = row16((const u16 *)px + (unsigned long)r * w, w, threshold_dn * 257.0f);
        else
            return -2;
    }
    reject_isolated(out, h);
    return height;
}
