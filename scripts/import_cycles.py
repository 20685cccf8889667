#!/usr/bin/env python3
"""File-level import cycles in a Rust crate's src/ tree.

    scripts/import_cycles.py [SRC_DIR ...]     (default: every src/ of the workspace)

Every `use crate::..` / `use super::..` / `use self::..` (brace groups expanded) and every
inline `crate::a::b` path is resolved to the file that defines the item: a path is walked
down the module files as far as they go, and a name a module file only re-exports
(`pub use child::Name`, `pub use child::*`) is followed to the file that defines it. A
`pub use` counts as a dependency of its own file only when the name is also used in that file's
body. Test modules (`#[cfg(test)] mod tests { .. }`) count like the rest. Prints each strongly
connected component of more than one file with the edges inside it and exits 1 if there is one.
"""
import os
import re
import sys
from collections import defaultdict

USE_RE = re.compile(r"\b(pub(?:\([^)]*\))?\s+)?use\s+([^;]+);", re.S)
INLINE_RE = re.compile(r"\b((?:crate|super|self)(?:::[A-Za-z_][A-Za-z0-9_]*)+)")
INLINE_MOD_RE = re.compile(r"^\s*(?:pub(?:\([^)]*\))?\s+)?mod\s+(\w+)\s*\{")
DEF_RE = r"\b(?:struct|enum|fn|type|trait|const|static|mod|union|macro_rules!)\s+{}\b"


def strip_comments(text):
    text = re.sub(r"/\*.*?\*/", "", text, flags=re.S)
    text = re.sub(r"//[^\n]*", "", text)
    # string literals: drop their contents (keep the quotes), so paths in strings do not count
    text = re.sub(r'"(?:\\.|[^"\\])*"', '""', text)
    return text


def expand_tree(tree):
    """`a::{b, c::{d, e as f}}` -> [[a,b], [a,c,d], [a,c,e]] (renames dropped)."""
    tree = re.sub(r"\s+", "", tree)

    def parse(s, i):
        out = []
        prefix = []
        tok = ""
        while i < len(s):
            ch = s[i]
            if s.startswith("::", i):
                if tok:
                    prefix.append(tok)
                    tok = ""
                i += 2
            elif ch == "{":
                inner, i = parse(s, i + 1)
                for p in inner:
                    out.append(prefix + p)
                prefix = []
            elif ch == "}":
                if tok or prefix:
                    out.append(prefix + ([tok] if tok else []))
                return out, i + 1
            elif ch == ",":
                if tok or prefix:
                    out.append(prefix + ([tok] if tok else []))
                prefix, tok = [], ""
                i += 1
            else:
                tok += ch
                i += 1
        if tok or prefix:
            out.append(prefix + ([tok] if tok else []))
        return out, i

    paths, _ = parse(tree, 0)
    return paths


def expand_use(raw):
    # keep `as` renames apart before removing whitespace
    raw = re.sub(r"\s+as\s+\w+", "", raw)
    return expand_tree(raw)


class Crate:
    def __init__(self, src):
        self.src = src
        self.files = {}  # module path tuple -> file
        self.text = {}  # file -> stripped text
        for root, _, names in os.walk(src):
            for n in names:
                if not n.endswith(".rs"):
                    continue
                f = os.path.join(root, n)
                rel = os.path.relpath(f, src)
                if rel.startswith("bin" + os.sep) or rel == "main.rs":
                    continue
                parts = rel[:-3].split(os.sep)
                if parts[-1] in ("mod", "lib"):
                    parts = parts[:-1]
                self.files[tuple(parts)] = f
                with open(f, encoding="utf-8") as h:
                    self.text[f] = strip_comments(h.read())
        self.modpath = {f: m for m, f in self.files.items()}
        self.reexports = {f: self._reexports(f) for f in self.text}

    def _reexports(self, f):
        """name -> absolute path list, and glob targets, for `pub use` in file f."""
        names, globs = {}, []
        for m in USE_RE.finditer(self.text[f]):
            if not m.group(1):
                continue
            for p in expand_use(m.group(2)):
                ap = self.absolute(f, p, 0)
                if ap is None:
                    continue
                if p[-1] == "*":
                    globs.append(ap[:-1])
                else:
                    names[p[-1]] = ap
        return names, globs

    def absolute(self, f, path, inline_depth):
        base = list(self.modpath[f])
        if path[0] == "crate":
            return path[1:]
        if path[0] in ("super", "self"):
            cur = base + ["<inline>"] * inline_depth
            i = 0
            if path[0] == "self":
                i = 1
            while i < len(path) and path[i] == "super":
                cur = cur[:-1]
                i += 1
            cur = [c for c in cur if c != "<inline>"]
            return cur + path[i:]
        # a sibling/child module name used bare (2018 paths): only if it is a child module
        if tuple(base + [path[0]]) in self.files:
            return base + path
        return None

    def defines(self, f, name):
        return re.search(DEF_RE.format(re.escape(name)), self.text[f]) is not None

    def resolve(self, path, seen=None):
        """Absolute path (without `crate`) -> the file defining it, or None."""
        seen = seen or set()
        key = tuple(path)
        if key in seen:
            return None
        seen.add(key)
        i = len(path)
        while i > 0 and tuple(path[:i]) not in self.files:
            i -= 1
        f = self.files.get(tuple(path[:i]))
        if f is None:
            return None
        rest = path[i:]
        if not rest or rest[0] == "*":
            return f
        names, globs = self.reexports[f]
        name = rest[0]
        if name in names and not self.defines(f, name):
            target = self.resolve(names[name] + rest[1:], seen)
            return target or f
        if not self.defines(f, name):
            for g in globs:
                t = self.resolve(g + [name] + rest[1:], seen)
                if t:
                    return t
        return f

    def edges(self, f):
        text = self.text[f]
        out = set()
        lines = text.split("\n")
        # inline module depth per character offset, from `mod x {` blocks
        depth_at = []
        stack = []
        level = 0
        for line in lines:
            m = INLINE_MOD_RE.match(line)
            if m:
                stack.append(level)
            depth_at.append(len(stack))
            level += line.count("{") - line.count("}")
            while stack and level <= stack[-1]:
                stack.pop()
        offsets = []
        pos = 0
        for line in lines:
            offsets.append(pos)
            pos += len(line) + 1

        def depth(off):
            lo, hi = 0, len(offsets) - 1
            while lo < hi:
                mid = (lo + hi + 1) // 2
                if offsets[mid] <= off:
                    lo = mid
                else:
                    hi = mid - 1
            return depth_at[lo]

        use_spans = []
        for m in USE_RE.finditer(text):
            use_spans.append((m.start(), m.end()))
            d = depth(m.start())
            for p in expand_use(m.group(2)):
                ap = self.absolute(f, p, d)
                if ap is None:
                    continue
                if m.group(1) and p[-1] != "*":
                    body = text[: m.start()] + text[m.end():]
                    body = re.sub(r"\bmod\s+\w+\s*;", "", body)
                    if not re.search(r"\b{}\b".format(re.escape(p[-1])), body):
                        continue
                if m.group(1) and p[-1] == "*":
                    continue
                t = self.resolve(ap)
                if t and t != f:
                    out.add(t)
        for m in INLINE_RE.finditer(text):
            if any(a <= m.start() < b for a, b in use_spans):
                continue
            ap = self.absolute(f, m.group(1).split("::"), depth(m.start()))
            if ap is None:
                continue
            t = self.resolve(ap)
            if t and t != f:
                out.add(t)
        return out


def sccs(graph):
    index, low, on, stack, out = {}, {}, set(), [], []
    counter = [0]
    sys.setrecursionlimit(10000)

    def visit(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in graph[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            out.append(comp)

    for v in list(graph):
        if v not in index:
            visit(v)
    return out


def main():
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    srcs = sys.argv[1:]
    if not srcs:
        for d, dirs, _ in os.walk(root):
            dirs[:] = [x for x in dirs if x not in ("target", ".git", "node_modules")]
            if os.path.basename(d) == "src" and os.path.exists(os.path.join(os.path.dirname(d), "Cargo.toml")):
                srcs.append(d)
    bad = 0
    nfiles = 0
    for src in sorted(srcs):
        c = Crate(src)
        graph = defaultdict(set)
        for f in c.text:
            graph[f] = c.edges(f)
        nfiles += len(graph)
        for comp in sccs(graph):
            if len(comp) < 2:
                continue
            bad += 1
            names = sorted(os.path.relpath(x, root) for x in comp)
            print("cycle: " + ", ".join(names))
            for a in sorted(comp):
                for b in sorted(graph[a]):
                    if b in comp:
                        print("    {} -> {}".format(os.path.relpath(a, root), os.path.relpath(b, root)))
    print("{} files in {} source trees, {} import cycle(s)".format(nfiles, len(srcs), bad))
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
