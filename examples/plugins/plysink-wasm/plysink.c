/*
 * A footscan sink as a wasm module (ABI 1, docs/plugins.md): reads the scan directory it is
 * granted (read-only, `grant = "scan"`) through WASI and reports what points.ply holds
 * against what the summary says. It imports only WASI's path_open, fd_read and fd_close, so
 * without a grant it is refused at start.
 *
 * Freestanding C (no wasi-libc needed: the three imports are declared here). Build:
 *
 *   clang --target=wasm32 -O2 -nostdlib -Wl,--no-entry -I.. -o plysink.wasm plysink.c
 *
 * Input: the scan summary as JSON. Report: "points.ply <vertices> vertices, <bytes> bytes;
 * summary points <n>: agree" (or "differ"). Error codes: -1 points.ply cannot be opened,
 * -2 it has no "element vertex" line in its header.
 */

#include "footscan_abi.h"

struct iovec { u8 *buf; u32 len; };

WASI("path_open") int path_open(int dirfd, int dirflags, const char *path, int path_len,
                                int oflags, u64 rights, u64 inheriting, int fdflags, int *fd);
WASI("fd_read") int fd_read(int fd, const struct iovec *iovs, int n, u32 *nread);
WASI("fd_close") int fd_close(int fd);

#define GRANTED_DIR 3 /* the one preopened directory */
#define FD_READ_RIGHT 2ull

static int starts(const u8 *s, const u8 *end, const char *p) {
    for (; *p; p++, s++)
        if (s >= end || *s != (u8)*p) return 0;
    return 1;
}

/* The number after `key` in `s..end`, or -1. */
static long long number_after(const u8 *s, const u8 *end, const char *key) {
    for (; s < end; s++) {
        if (!starts(s, end, key)) continue;
        const char *k = key;
        while (*k) { k++; s++; }
        while (s < end && (*s == ' ' || *s == ':')) s++;
        long long v = 0;
        int digits = 0;
        while (s < end && *s >= '0' && *s <= '9') { v = v * 10 + (*s++ - '0'); digits++; }
        return digits ? v : -1;
    }
    return -1;
}

static void put_str(char *out, int *at, int cap, const char *s) {
    while (*s && *at < cap) out[(*at)++] = *s++;
}

static void put_int(char *out, int *at, int cap, long long v) {
    char buf[24];
    int n = 0;
    if (v < 0) { put_str(out, at, cap, "-"); v = -v; }
    do { buf[n++] = (char)('0' + v % 10); v /= 10; } while (v);
    while (n-- && *at < cap) out[(*at)++] = buf[n];
}

static u8 chunk[65536];

EXPORT("footscan_sink") int footscan_sink(const u8 *summary, int len, char *out, int cap) {
    int fd;
    if (path_open(GRANTED_DIR, 0, "points.ply", 10, 0, FD_READ_RIGHT, 0, 0, &fd) != 0) return -1;
    u64 total = 0;
    long long vertices = -1;
    for (;;) {
        struct iovec v = {chunk, sizeof chunk};
        u32 got = 0;
        if (fd_read(fd, &v, 1, &got) != 0 || got == 0) break;
        if (total == 0) vertices = number_after(chunk, chunk + got, "element vertex ");
        total += got;
    }
    fd_close(fd);
    if (vertices < 0) return -2;
    long long points = number_after(summary, summary + len, "\"points\"");
    int at = 0;
    put_str(out, &at, cap, "points.ply ");
    put_int(out, &at, cap, vertices);
    put_str(out, &at, cap, " vertices, ");
    put_int(out, &at, cap, (long long)total);
    put_str(out, &at, cap, " bytes; summary points ");
    put_int(out, &at, cap, points);
    put_str(out, &at, cap, vertices == points ? ": agree\n" : ": differ\n");
    return at;
}
