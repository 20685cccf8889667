/*
 * What every freestanding C footscan wasm stage shares (ABI 1, docs/plugins.md): the integer
 * names, the export and WASI-import attributes, the ABI version export and the allocator the
 * host calls to place its input. Include it and build with `-I examples/plugins`:
 *
 *   clang --target=wasm32 -O2 -nostdlib -Wl,--no-entry -I examples/plugins -o x.wasm x.c
 */
#ifndef FOOTSCAN_ABI_H
#define FOOTSCAN_ABI_H

typedef unsigned char u8;
typedef unsigned short u16;
typedef unsigned int u32;
typedef unsigned long long u64;

#define EXPORT(name) __attribute__((export_name(name)))
#define WASI(name) __attribute__((import_module("wasi_snapshot_preview1"), import_name(name)))

EXPORT("footscan_abi") int footscan_abi(void) { return 1; }

/* A bump allocator over the memory after the data: the host calls it only when an input's
 * size changes (a frame's shape, a scan's points), so nothing is freed. */
extern u8 __heap_base;
static unsigned long heap_top;

EXPORT("footscan_alloc") int footscan_alloc(int size) {
    if (size < 0) return 0;
    if (!heap_top) heap_top = (unsigned long)&__heap_base;
    unsigned long start = (heap_top + 15) & ~15ul;
    unsigned long end = start + (unsigned long)size;
    unsigned long have = __builtin_wasm_memory_size(0) * 65536ul;
    if (end > have) {
        unsigned long pages = (end - have + 65535) / 65536;
        if (__builtin_wasm_memory_grow(0, pages) == (unsigned long)-1) return 0;
    }
    heap_top = end;
    return (int)start;
}

#endif
