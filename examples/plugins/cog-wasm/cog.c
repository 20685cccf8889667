/*
 * A centre-of-gravity laser-line detector as a footscan wasm stage (ABI 1, docs/plugins.md).
 *
 * Freestanding C: no libc, no WASI, no imports, so the host grants it nothing. Build with
 * Debian's clang and lld (from examples/plugins/cog-wasm):
 *
 *   clang --target=wasm32 -O2 -msimd128 -nostdlib -Wl,--no-entry -I.. -o cog.wasm cog.c
 *
 * -msimd128 lets every per-row search look at 16 (8-bit) or 8 (16-bit) pixels at a time with
 * WebAssembly's 128-bit SIMD, which wasmtime compiles to SSE/NEON; without it the same C runs
 * one pixel at a time (about 20x the built-in's time instead of under 2x: docs/method.md
 * section 14d.5). The results are the same either way.
 *
 * Per row it does what the built-in `detect.cog` does with a fixed threshold, the ambiguity
 * test off (ambiguity > 1) and specular spikes not skipped: the first maximum, its flat top,
 * the run above the threshold, the border test, the background beside the run, the width at
 * half height and the run, each crossing dips that the line comes back from within its width
 * (speckle), the saturation test, the centre of gravity of (value - threshold) over the run,
 * then rows with no other line within 2 rows rejected as isolated. The arithmetic is the
 * built-in's, in the same precision (the centre of gravity's sums in another order, but exact:
 * see cog8 below), so the columns are equal bit for bit (tests/plugin_wasm.rs checks it on
 * simulated frames, at a whole and a fractional threshold, SIMD and scalar builds).
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

/*
 * The per-row searches. With -msimd128 each looks at 16 (8-bit) or 8 (16-bit) pixels at a
 * time; without it, one. Both give the same indices. Why SIMD even for walks of a few pixels:
 * the host's time limit puts a check at every loop header, and a scalar walk's exit is a
 * branch the CPU cannot predict; one vector compare and a bit scan replace both (docs/method.md
 * section 14d.5).
 *
 * Tests a pixel x against s: EQ x == s, GT x > s, GE x >= s, LT x < s. Pixels are integers, so
 * `(float)x > thr` is `x > floor(thr)` and `(float)x >= half` is `x >= ceil(half)`.
 */
enum { EQ, GT, GE, LT };

#define INLINE static inline __attribute__((always_inline))

INLINE int passes(u32 x, u32 s, int kind) {
    return kind == EQ ? x == s : kind == GT ? x > s : kind == GE ? x >= s : x < s;
}

#ifdef __wasm_simd128__
#include <wasm_simd128.h>

INLINE u32 pass8(v128_t x, v128_t s, int kind) {
    v128_t m = kind == EQ ? wasm_i8x16_eq(x, s)
              : kind == GT ? wasm_u8x16_gt(x, s)
              : kind == GE ? wasm_u8x16_ge(x, s)
                           : wasm_u8x16_lt(x, s);
    return (u32)wasm_i8x16_bitmask(m);
}
INLINE u32 pass16(v128_t x, v128_t s, int kind) {
    v128_t m = kind == EQ ? wasm_i16x8_eq(x, s)
              : kind == GT ? wasm_u16x8_gt(x, s)
              : kind == GE ? wasm_u16x8_ge(x, s)
                           : wasm_u16x8_lt(x, s);
    return (u32)wasm_i16x8_bitmask(m);
}
#define SPLAT8(s) wasm_i8x16_splat((signed char)(s))
#define SPLAT16(s) wasm_i16x8_splat((short)(s))

/* right: the first index in [i, end) whose pixel fails, or end.
 * left: the smallest j <= e with every pixel of [j, e) passing and j >= lo. */
#define WALKS(T, SFX, LANES, PASS, SPLAT)                                                      \
    INLINE u32 right##SFX(const T *row, u32 i, u32 end, u32 s, int kind) {                    \
        v128_t sv = SPLAT(s);                                                                 \
        for (; i + LANES <= end; i += LANES) {                                                \
            u32 fail = ~PASS(wasm_v128_load(row + i), sv, kind) & ((1u << LANES) - 1);        \
            if (fail) return i + (u32)__builtin_ctz(fail);                                    \
        }                                                                                     \
        while (i < end && passes(row[i], s, kind)) i++;                                       \
        return i;                                                                             \
    }                                                                                         \
    INLINE u32 left##SFX(const T *row, u32 e, u32 lo, u32 s, int kind) {                      \
        v128_t sv = SPLAT(s);                                                                 \
        for (; e >= lo + LANES; e -= LANES) {                                                 \
            u32 fail = ~PASS(wasm_v128_load(row + e - LANES), sv, kind) & ((1u << LANES) - 1); \
            if (fail) return e - LANES + (31 - (u32)__builtin_clz(fail)) + 1;                 \
        }                                                                                     \
        while (e > lo && passes(row[e - 1], s, kind)) e--;                                    \
        return e;                                                                             \
    }
WALKS(u8, 8, 16, pass8, SPLAT8)
WALKS(u16, 16, 8, pass16, SPLAT16)

/* Largest lane, by halving: four (8-bit) or three (16-bit) shuffles instead of a store and a
 * loop over the lanes. */
static inline u32 hmax8(v128_t m) {
    m = wasm_u8x16_max(m, wasm_i32x4_shuffle(m, m, 2, 3, 0, 1));
    m = wasm_u8x16_max(m, wasm_i32x4_shuffle(m, m, 1, 0, 3, 2));
    m = wasm_u8x16_max(m, wasm_i16x8_shuffle(m, m, 1, 0, 3, 2, 5, 4, 7, 6));
    m = wasm_u8x16_max(m, wasm_i8x16_shuffle(m, m, 1, 0, 3, 2, 5, 4, 7, 6, 9, 8, 11, 10, 13, 12, 15, 14));
    return wasm_u8x16_extract_lane(m, 0);
}
static inline u32 hmax16(v128_t m) {
    m = wasm_u16x8_max(m, wasm_i32x4_shuffle(m, m, 2, 3, 0, 1));
    m = wasm_u16x8_max(m, wasm_i32x4_shuffle(m, m, 1, 0, 3, 2));
    m = wasm_u16x8_max(m, wasm_i16x8_shuffle(m, m, 1, 0, 3, 2, 5, 4, 7, 6));
    return wasm_u16x8_extract_lane(m, 0);
}

/* The row's maximum in *vout and, if it is above thr, the index of its first occurrence
 * (0 otherwise: a row below the threshold needs no position). 128 bytes an iteration for the
 * maximum and 64 for where it first is: fewer loop headers, so fewer of the time limit's
 * checks. */
#define ARGMAX(T, SFX, LANES, MAX, HMAX, SPLAT, EQV, BITMASK)                                  \
    static u32 argmax##SFX(const T *row, u32 w, float thr, T *vout) {                         \
        v128_t m[8];                                                                          \
        for (int k = 0; k < 8; k++) m[k] = wasm_i8x16_splat(0);                               \
        u32 i = 0;                                                                            \
        for (; i + 8 * LANES <= w; i += 8 * LANES)                                            \
            for (int k = 0; k < 8; k++) m[k] = MAX(m[k], wasm_v128_load(row + i + k * LANES)); \
        for (; i + LANES <= w; i += LANES) m[0] = MAX(m[0], wasm_v128_load(row + i));         \
        for (int k = 1; k < 8; k++) m[0] = MAX(m[0], m[k]);                                   \
        u32 v = HMAX(m[0]);                                                                   \
        for (; i < w; i++) v = row[i] > v ? row[i] : v;                                       \
        *vout = (T)v;                                                                         \
        if ((float)v <= thr) return 0;                                                        \
        v128_t sv = SPLAT(v);                                                                 \
        for (i = 0; i + 4 * LANES <= w; i += 4 * LANES) {                                     \
            u64 hit = 0;                                                                      \
            for (int k = 0; k < 4; k++)                                                       \
                hit |= (u64)(u32)BITMASK(EQV(wasm_v128_load(row + i + k * LANES), sv))        \
                       << (k * LANES);                                                        \
            if (hit) return i + (u32)__builtin_ctzll(hit);                                    \
        }                                                                                     \
        return right##SFX(row, i, w, v, LT); /* the first pixel not below the maximum */      \
    }
ARGMAX(u8, 8, 16, wasm_u8x16_max, hmax8, SPLAT8, wasm_i8x16_eq, wasm_i8x16_bitmask)
ARGMAX(u16, 16, 8, wasm_u16x8_max, hmax16, SPLAT16, wasm_i16x8_eq, wasm_i16x8_bitmask)
/* The centre of gravity's sums over [lo, hi], four pixels at a time. The weights are the same
 * f32 values as the scalar loop's; each is a multiple of the threshold's ulp, so while a sum
 * needs at most 53 bits it is exact in f64 and its order does not matter: with a threshold of
 * at least 1 DN, for runs of up to 1,024 pixels (a laser line's is tens). The column is then
 * the scalar loop's bit for bit. */
#define COG(T, SFX, LOAD4)                                                                     \
    INLINE void cog##SFX(const T *row, u32 lo, u32 hi, float thr, double *s, double *sx) {    \
        v128_t t = wasm_f32x4_splat(thr);                                                     \
        v128_t s0 = wasm_f64x2_splat(0.0), s1 = s0, x0 = s0, x1 = s0;                         \
        v128_t i0 = wasm_f64x2_make((double)lo, (double)lo + 1.0);                            \
        v128_t i1 = wasm_f64x2_add(i0, wasm_f64x2_splat(2.0)), four = wasm_f64x2_splat(4.0);  \
        u32 i = lo;                                                                           \
        for (; i + 4 <= hi + 1; i += 4) {                                                     \
            v128_t w = wasm_f32x4_sub(wasm_f32x4_convert_u32x4(LOAD4(row + i)), t);           \
            v128_t a = wasm_f64x2_promote_low_f32x4(w);                                       \
            v128_t b = wasm_f64x2_promote_low_f32x4(wasm_i32x4_shuffle(w, w, 2, 3, 0, 1));    \
            s0 = wasm_f64x2_add(s0, a);                                                       \
            s1 = wasm_f64x2_add(s1, b);                                                       \
            x0 = wasm_f64x2_add(x0, wasm_f64x2_mul(a, i0));                                   \
            x1 = wasm_f64x2_add(x1, wasm_f64x2_mul(b, i1));                                   \
            i0 = wasm_f64x2_add(i0, four);                                                    \
            i1 = wasm_f64x2_add(i1, four);                                                    \
        }                                                                                     \
        s0 = wasm_f64x2_add(s0, s1);                                                          \
        x0 = wasm_f64x2_add(x0, x1);                                                          \
        double ss = wasm_f64x2_extract_lane(s0, 0) + wasm_f64x2_extract_lane(s0, 1);          \
        double sxx = wasm_f64x2_extract_lane(x0, 0) + wasm_f64x2_extract_lane(x0, 1);         \
        for (; i <= hi; i++) {                                                                \
            double wgt = (double)((float)row[i] - thr);                                       \
            ss += wgt;                                                                        \
            sxx += wgt * (double)i;                                                           \
        }                                                                                     \
        *s = ss;                                                                              \
        *sx = sxx;                                                                            \
    }
#define LOAD4_8(p) wasm_u32x4_extend_low_u16x8(wasm_u16x8_extend_low_u8x16(wasm_v128_load32_zero(p)))
#define LOAD4_16(p) wasm_u32x4_extend_low_u16x8(wasm_v128_load64_zero(p))
COG(u8, 8, LOAD4_8)
COG(u16, 16, LOAD4_16)
#else
#define WALKS(T, SFX)                                                                          \
    INLINE u32 right##SFX(const T *row, u32 i, u32 end, u32 s, int kind) {                    \
        while (i < end && passes(row[i], s, kind)) i++;                                       \
        return i;                                                                             \
    }                                                                                         \
    INLINE u32 left##SFX(const T *row, u32 e, u32 lo, u32 s, int kind) {                      \
        while (e > lo && passes(row[e - 1], s, kind)) e--;                                    \
        return e;                                                                             \
    }                                                                                         \
    static u32 argmax##SFX(const T *row, u32 w, float thr, T *vout) {                         \
        T v = 0;                                                                              \
        u32 pos = 0;                                                                          \
        for (u32 i = 0; i < w; i++)                                                           \
            if (row[i] > v) { v = row[i]; pos = i; }                                          \
        *vout = v;                                                                            \
        return (float)v <= thr ? 0 : pos;                                                     \
    }
WALKS(u8, 8)
WALKS(u16, 16)
#define COG(T, SFX)                                                                            \
    INLINE void cog##SFX(const T *row, u32 lo, u32 hi, float thr, double *s, double *sx) {    \
        for (u32 i = lo; i <= hi; i++) {                                                      \
            double wgt = (double)((float)row[i] - thr);                                       \
            *s += wgt;                                                                        \
            *sx += wgt * (double)i;                                                           \
        }                                                                                     \
    }
COG(u8, 8)
COG(u16, 16)
#endif

/* One row of `w` pixels of type T, full scale FULL, cut at `thr` (frame units). */
#define ROW_FN(NAME, T, FULL, SFX)                                                             \
    static struct row_out NAME(const T *row, u32 w, float thr) {                              \
        if (w < 3) return rejected(BORDER, 0.0f);                                             \
        T v = 0;                                                                              \
        u32 pos = argmax##SFX(row, w, thr, &v);                                               \
        float top = (float)v;                                                                 \
        if (top <= thr) return rejected(BELOW_THRESHOLD, top);                                \
        u32 a = left##SFX(row, pos, 0, v, EQ);                                                \
        u32 b = right##SFX(row, pos + 1, w, v, EQ) - 1;                                       \
        u32 saturated = top >= (float)(FULL) ? b - a + 1 : 0;                                 \
        u32 t = (u32)thr; /* floor: thr > 0 */                                                \
        u32 lo = left##SFX(row, a, 0, t, GT);                                                 \
        u32 hi = right##SFX(row, b + 1, w, t, GT) - 1;                                        \
        if (lo == 0 || hi + 1 == w) return rejected(BORDER, top);                             \
        float bg = minf((float)row[lo - 1], (float)row[hi + 1]);                              \
        if (lo >= 2) bg = minf(bg, (float)row[lo - 2]);                                       \
        if (hi + 2 < w) bg = minf(bg, (float)row[hi + 2]);                                    \
        float half = bg + 0.5f * (top - bg);                                                  \
        u32 ih = (u32)__builtin_ceilf(half);                                                  \
        u32 l = left##SFX(row, a, lo, ih, GE);                                                \
        u32 r = right##SFX(row, b + 1, hi + 1, ih, GE) - 1;                                   \
        /* A dip under half height is crossed when the line is back at half height within     \
         * the width found so far, inside the run (speckle on a wide line). */                \
        for (;;) {                                                                            \
            u32 reach = r + 1 - l, l0 = l, r0 = r;                                            \
            u32 stop = l > lo + reach ? l - reach : lo;                                       \
            u32 e = left##SFX(row, l, stop, ih, LT);                                          \
            if (e > stop) l = left##SFX(row, e, lo, ih, GE);                                  \
            stop = r + reach < hi ? r + reach : hi;                                           \
            u32 j = right##SFX(row, r + 1, stop + 1, ih, LT);                                 \
            if (j <= stop) r = right##SFX(row, j, hi + 1, ih, GE) - 1;                        \
            if (l == l0 && r == r0) break;                                                    \
        }                                                                                     \
        float v0 = (float)row[l - 1], v1 = (float)row[l];                                     \
        float xl = (float)(l - 1) + clampf((half - v0) / maxf(v1 - v0, 1e-6f), 0.0f, 1.0f);   \
        v0 = (float)row[r];                                                                   \
        v1 = (float)row[r + 1];                                                               \
        float xr = (float)r + clampf((v0 - half) / maxf(v0 - v1, 1e-6f), 0.0f, 1.0f);         \
        float width = maxf(xr - xl, 0.5f);                                                    \
        /* The run crosses a dip under the threshold when the line is back above it within    \
         * its width: the other half of a speckled wide line is not a second peak. */         \
        for (u32 reach = (u32)width;;) {                                                      \
            u32 lo0 = lo, hi0 = hi;                                                           \
            u32 stop = lo > reach + 1 ? lo - reach : 1;                                       \
            if (lo >= 2 && lo - 1 > stop) {                                                   \
                u32 e = left##SFX(row, lo - 1, stop, t + 1, LT);                              \
                if (e > stop) {                                                               \
                    u32 nl = left##SFX(row, e, 0, t, GT);                                     \
                    if (nl > 0) lo = nl;                                                      \
                }                                                                             \
            }                                                                                 \
            stop = hi + reach < w - 2 ? hi + reach : w - 2;                                   \
            if (hi + 2 <= stop) {                                                             \
                u32 j = right##SFX(row, hi + 2, stop + 1, t + 1, LT);                         \
                if (j <= stop) {                                                              \
                    u32 nh = right##SFX(row, j, w, t, GT) - 1;                                \
                    if (nh + 1 < w) hi = nh;                                                  \
                }                                                                             \
            }                                                                                 \
            if (lo == lo0 && hi == hi0) break;                                                \
        }                                                                                     \
        /* Over-exposed: clipped over more than max_saturated_px and over half the width. */  \
        if (saturated > max_saturated_px && (float)saturated > 0.5f * width)                  \
            return rejected(SATURATED, top);                                                  \
        double s = 0.0, sx = 0.0;                                                             \
        cog##SFX(row, lo, hi, thr, &s, &sx);                                                  \
        if (s <= 0.0) return rejected(BELOW_THRESHOLD, top);                                  \
        float full = (float)(FULL);                                                           \
        float sig = clampf((top - thr) / maxf(0.5f * full - thr, 1.0f), 0.0f, 1.0f);          \
        float uniq = 1.0f; /* no second peak is looked for: the ambiguity test is off */      \
        float sat = saturated > 0 ? 0.5f : 1.0f;                                              \
        struct row_out o = {sx / s, top, width, sig * uniq * sat, ACCEPTED};                  \
        return o;                                                                             \
    }

ROW_FN(row8, u8, 255, 8)
ROW_FN(row16, u16, 65535, 16)

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
