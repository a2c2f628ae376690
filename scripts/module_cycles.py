#!/usr/bin/env python3
"""Checks that every crate's modules form a one-way stack: no import cycles.

Usage: scripts/module_cycles.py [--order] [CRATE_DIR ...]

With no directories, checks every crate of the repository (each directory with
a Cargo.toml and a src/lib.rs, src/main.rs or src/bin/*.rs), skipping target/
and fuzz/. Exit status 1 when some crate has a cycle; each cycle is printed with
the file and line of every import that closes it. `--order` also prints each
crate's modules bottom-up (every module imports only modules above it in the
list).

What counts as an import: a path in code (not comments, strings or doc links)
that names another module of the same crate: `crate::a::b`, `super::x`,
`self::x`, or a child module by its bare name. Code under `#[cfg(test)]` is left
out (tests may look anywhere). A path that names a re-export is followed to the
module that defines the item, so `use crate::Error` in a module is an import of
`error`, not of the crate root. The crate root may import every module (it is the
facade), and nothing imports from it but its re-exports: an item defined in the
root itself and used by a module would close a cycle through the root, and is
reported as one.

Upper layers (`UPPER_LAYERS`): a top-level module that only the crate root and
its own submodules may import. The facade's `jobs` (batch jobs) sits above the
library a renderer links; a library module that imports it, directly or through
the root's re-exports (`crate::config`), fails the check.
"""

import os
import re
import sys

IDENT = r"[A-Za-z_][A-Za-z0-9_]*"

# Per crate root (relative to the repository), the top-level modules that no
# module outside them imports.
UPPER_LAYERS = {"src/lib.rs": ("jobs",)}


def strip_code(text):
    """Blanks comments, string and char literals, keeping line breaks."""
    out = []
    i, n = 0, len(text)
    while i < n:
        c = text[i]
        if text.startswith("//", i):
            j = text.find("\n", i)
            j = n if j < 0 else j
            i = j
            continue
        if text.startswith("/*", i):
            depth, j = 1, i + 2
            while j < n and depth:
                if text.startswith("/*", j):
                    depth, j = depth + 1, j + 2
                elif text.startswith("*/", j):
                    depth, j = depth - 1, j + 2
                else:
                    j += 1
            out.append("\n" * text.count("\n", i, j))
            i = j
            continue
        m = re.match(r'b?r(#*)"', text[i:i + 260]) if c in "rb" else None
        if m and (i == 0 or not re.match(r"[A-Za-z0-9_]", text[i - 1])):
            close = '"' + m.group(1)
            j = text.find(close, i + m.end())
            j = n if j < 0 else j + len(close)
            out.append('""' + "\n" * text.count("\n", i, j))
            i = j
            continue
        if c == '"':
            j = i + 1
            while j < n and text[j] != '"':
                j += 2 if text[j] == "\\" else 1
            j += 1
            out.append('""' + "\n" * text.count("\n", i, j))
            i = j
            continue
        if c == "'":
            m = re.match(r"'(\\.[^']*|[^\\'\n])'", text[i:i + 12])
            if m:
                out.append("' '")
                i += m.end()
                continue
        out.append(c)
        i += 1
    return "".join(out)


def matching_brace(text, i):
    """Index just past the brace block that starts at or after `i`."""
    i = text.index("{", i)
    depth = 0
    for j in range(i, len(text)):
        if text[j] == "{":
            depth += 1
        elif text[j] == "}":
            depth -= 1
            if depth == 0:
                return j + 1
    return len(text)


def drop_test_items(code):
    """Blanks every item under `#[cfg(test)]` (keeping line breaks)."""
    pattern = re.compile(r"#\[cfg\((?:all\()?test\b")
    while True:
        m = pattern.search(code)
        if not m:
            return code
        start, j = m.start(), m.end()
        # The item ends at its first `;` or at the end of its first brace block,
        # whichever comes first.
        semi = code.find(";", j)
        brace = code.find("{", j)
        if brace >= 0 and (semi < 0 or brace < semi):
            end = matching_brace(code, brace)
        else:
            end = semi + 1 if semi >= 0 else len(code)
        code = code[:start] + "\n" * code.count("\n", start, end) + code[end:]


def expand_use_tree(tree):
    """`a::{b, c::{d, e}}` -> [['a','b'], ['a','c','d'], ['a','c','e']]."""
    tree = re.sub(r"\s+", "", tree)
    tree = re.sub(r"\bas" + IDENT, "", tree)

    def parse(s, i):
        paths, prefix = [], []
        while i < len(s):
            if s[i] == "{":
                inner, i = parse_group(s, i + 1)
                paths += [prefix + p for p in inner]
                prefix = None
            elif s.startswith("::", i):
                i += 2
                continue
            elif s[i] in ",}":
                break
            else:
                m = re.match(IDENT + r"|\*", s[i:])
                if not m:
                    i += 1
                    continue
                prefix = (prefix or []) + [m.group(0)]
                i += m.end()
                continue
        if prefix:
            paths.append(prefix)
        return paths, i

    def parse_group(s, i):
        paths = []
        while i < len(s) and s[i] != "}":
            p, i = parse(s, i)
            paths += p
            if i < len(s) and s[i] == ",":
                i += 1
        return paths, i + 1

    return parse(tree, 0)[0]


class Module:
    def __init__(self, name, path, file):
        self.name = name  # tuple of segments; () is the crate root
        self.path = path  # file path
        self.file = file  # (code text) after stripping
        self.children = {}  # bare name -> Module name tuple
        self.reexports = {}  # item name -> path segments (absolute)
        self.uses = []  # (line, absolute path segments)


def module_file(dir_, name):
    for cand in (os.path.join(dir_, name + ".rs"), os.path.join(dir_, name, "mod.rs")):
        if os.path.exists(cand):
            return cand
    return None


def load_crate(root_file):
    modules = {}

    def visit(name, path):
        text = open(path, encoding="utf-8").read()
        code = drop_test_items(strip_code(text))
        mod = Module(name, path, code)
        modules[name] = mod
        base = os.path.basename(path)
        if base in ("lib.rs", "main.rs", "mod.rs") or name == ():
            child_dir = os.path.dirname(path)
        else:
            child_dir = os.path.join(os.path.dirname(path), base[:-3])
        for m in re.finditer(r"^\s*(?:pub(?:\([^)]*\))?\s+)?mod\s+(" + IDENT + r")\s*;", code, re.M):
            child = m.group(1)
            file = module_file(child_dir, child)
            if file:
                mod.children[child] = name + (child,)
                visit(name + (child,), file)
        for m in re.finditer(r"^\s*(?:pub(?:\([^)]*\))?\s+)?mod\s+(" + IDENT + r")\s*\{", code, re.M):
            # An inline module: its imports count as the file's.
            mod.children.setdefault(m.group(1), None)

    visit((), root_file)
    return modules


def absolute(mod, segs, inline=0):
    """Absolute segments for a path written in `mod` (inside `inline` nested
    inline `mod x { ... }` blocks, whose `super` is the file's module), or
    None if external."""
    head = segs[0]
    while inline and head == "super":
        segs, inline = segs[1:], inline - 1
        head = segs[0] if segs else "self"
        if not segs:
            return list(mod.name)
    if head == "crate":
        return list(segs[1:])
    if head == "self":
        return list(mod.name) + list(segs[1:])
    if head == "super":
        base = list(mod.name)
        rest = list(segs)
        while rest and rest[0] == "super":
            base = base[:-1]
            rest = rest[1:]
        return base + rest
    if head in mod.children and mod.children[head] is not None:
        return list(mod.name) + list(segs)
    return None


def collect_uses(mod):
    code = mod.file
    taken = []
    blocks = [(m.start(), matching_brace(code, m.end() - 1))
              for m in re.finditer(r"\bmod\s+" + IDENT + r"\s*\{", code)]

    def inline(pos):
        return sum(1 for a, b in blocks if a < pos < b)

    for m in re.finditer(r"\b(pub(?:\([^)]*\))?\s+)?use\s+([^;]*);", code):
        line = code.count("\n", 0, m.start()) + 1
        taken.append((m.start(), m.end()))
        for segs in expand_use_tree(m.group(2)):
            if segs and segs[-1] == "self":
                segs = segs[:-1]
            if not segs:
                continue
            path = absolute(mod, segs, inline(m.start()))
            if path is None:
                continue
            mod.uses.append((line, path))
            if m.group(1) and segs[-1] not in ("*", "self"):
                mod.reexports[segs[-1]] = path
    # Paths in code outside `use` statements.
    names = "|".join(["crate", "super", "self"] + [c for c, v in mod.children.items() if v])
    pattern = re.compile(r"(?<![A-Za-z0-9_:])(?:" + names + r")(?:::" + IDENT + r")+")
    for m in pattern.finditer(code):
        if any(a <= m.start() < b for a, b in taken):
            continue
        segs = m.group(0).split("::")
        path = absolute(mod, segs, inline(m.start()))
        if path is not None:
            line = code.count("\n", 0, m.start()) + 1
            mod.uses.append((line, path))


def resolve(modules, path, depth=0):
    """The module that defines what `path` names."""
    name = ()
    i = 0
    while i < len(path) and name + (path[i],) in modules:
        name = name + (path[i],)
        i += 1
    if i < len(path) and depth < 16:
        item = path[i]
        target = modules[name].reexports.get(item)
        if target is not None and target != path:
            return resolve(modules, target, depth + 1)
    return name


def graph(modules):
    edges = {}
    for mod in modules.values():
        collect_uses(mod)
    for mod in modules.values():
        for line, path in mod.uses:
            target = resolve(modules, path)
            if target == mod.name:
                continue
            # A parent reaching into its own child through `mod` is structure,
            # but a `use` of it is an import like any other; the crate root is
            # the facade and imports freely.
            if mod.name == ():
                continue
            edges.setdefault(mod.name, {}).setdefault(target, []).append(line)
    return edges


def sccs(nodes, edges):
    index, low, stack, on, out = {}, {}, [], set(), []
    counter = [0]

    def strong(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in edges.get(v, {}):
            if w not in index:
                strong(w)
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

    sys.setrecursionlimit(10000)
    for v in nodes:
        if v not in index:
            strong(v)
    return out  # reverse topological: dependencies first


def show(name):
    return "::".join(name) if name else "(crate root)"


def crate_roots(dir_):
    src = os.path.join(dir_, "src")
    roots = []
    for f in ("lib.rs", "main.rs"):
        if os.path.exists(os.path.join(src, f)):
            roots.append(os.path.join(src, f))
    bins = os.path.join(src, "bin")
    if os.path.isdir(bins):
        for f in sorted(os.listdir(bins)):
            p = os.path.join(bins, f)
            if f.endswith(".rs"):
                roots.append(p)
            elif os.path.exists(os.path.join(p, "main.rs")):
                roots.append(os.path.join(p, "main.rs"))
    return roots


def find_crates(top):
    for dirpath, dirnames, filenames in os.walk(top):
        dirnames[:] = sorted(d for d in dirnames if d not in ("target", "fuzz", ".git", "node_modules") and not d.startswith("."))
        if "Cargo.toml" in filenames and crate_roots(dirpath):
            yield dirpath


def main(argv):
    order = "--order" in argv
    dirs = [a for a in argv if not a.startswith("--")]
    top = os.path.normpath(os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))
    if not dirs:
        dirs = list(find_crates(top))
    bad = 0
    for dir_ in dirs:
        for root in crate_roots(dir_):
            modules = load_crate(root)
            edges = graph(modules)
            comps = sccs(sorted(modules), edges)
            rel = os.path.relpath(root, top)
            cycles = [c for c in comps if len(c) > 1]
            # Folders too: a module with its submodules, taken as one node,
            # must not import and be imported by the same other folder.
            depth = max(len(n) for n in modules)
            for d in range(1, depth):
                folded = {}
                for a, targets in edges.items():
                    for b, lines in targets.items():
                        fa, fb = a[:d], b[:d]
                        if fa != fb:
                            folded.setdefault(fa, {}).setdefault(fb, []).extend(lines)
                nodes = sorted({n[:d] for n in modules})
                folders = [n for n in nodes if any(len(m) > d and m[:d] == n for m in modules)]
                for comp in sccs(nodes, folded):
                    if len(comp) > 1 and any(c in folders for c in comp) and comp not in cycles:
                        cycles.append(comp)
                        for a in comp:
                            for b, lines in folded.get(a, {}).items():
                                if b in comp:
                                    edges.setdefault(a, {}).setdefault(b, lines)
                                    modules.setdefault(a, Module(a, "(folder)", ""))
            if cycles:
                bad += 1
                print(f"{rel}: {len(cycles)} import cycle(s)")
                for comp in cycles:
                    members = set(comp)
                    print("  cycle: " + ", ".join(sorted(show(m) for m in comp)))
                    for a in sorted(comp):
                        for b, lines in sorted(edges.get(a, {}).items()):
                            if b in members:
                                path = os.path.relpath(modules[a].path, top)
                                print(f"    {show(a)} -> {show(b)}  ({path}:{','.join(map(str, sorted(set(lines))))})")
            root_uses = sorted((a, lines) for a, t in edges.items() for b, lines in t.items() if b == () and a != ())
            if root_uses:
                bad += 1
                print(f"{rel}: modules import items defined in the crate root (move them to a module):")
                for a, lines in root_uses:
                    path = os.path.relpath(modules[a].path, top)
                    print(f"    {show(a)} -> (crate root)  ({path}:{','.join(map(str, sorted(set(lines))))})")
            layer_uses = sorted(
                (a, b, lines)
                for a, t in edges.items()
                for b, lines in t.items()
                for layer in UPPER_LAYERS.get(rel, ())
                if a and a[0] != layer and b[:1] == (layer,)
            )
            if layer_uses:
                bad += 1
                print(f"{rel}: modules below an upper layer import it:")
                for a, b, lines in layer_uses:
                    path = os.path.relpath(modules[a].path, top)
                    print(f"    {show(a)} -> {show(b)}  ({path}:{','.join(map(str, sorted(set(lines))))})")
            if not cycles and not root_uses and not layer_uses:
                layers = "".join(f", nothing below imports {l}" for l in UPPER_LAYERS.get(rel, ()))
                print(f"{rel}: {len(modules)} modules, no import cycle{layers}")
            if order:
                print("  bottom-up: " + " < ".join(show(c[0]) if len(c) == 1 else "{" + ", ".join(show(m) for m in c) + "}" for c in comps))
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
