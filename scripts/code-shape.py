#!/usr/bin/env python3
"""The shape of the code a newcomer reads: file-level import circles and long functions.

    scripts/code-shape.py            print every circle and every function over the limit
    scripts/code-shape.py --check    the same, and exit 1 if there is any
    scripts/code-shape.py --top N    also list the N longest functions (under the limit too)

**Circles.** Inside each crate under `crates/`, a file (module) depends on another when its code
names an item the other defines: a `use crate::…`, `use super::…`, `use self::…` import or a
`crate::…` / `super::…` path in the code, resolved through `pub use` re-exports to the file that
*defines* the item (a re-export is a facade, not a dependency of the re-exporting file; a
`mod` declaration is not one either). `#[cfg(test)]` modules are left out (a test reads the
code it tests). A circle is a strongly connected set of two or more files; each is printed with
one edge list that closes it.

**Long functions.** Every `fn` with a body in `crates/*/{src,tests,examples,benches}` (and
`benches/`) longer than `LIMIT` lines, from its signature's first line to its closing brace.
"""

import pathlib
import re
import sys
from collections import defaultdict

ROOT = pathlib.Path(__file__).resolve().parent.parent
LIMIT = 120

ITEM = re.compile(
    r"^(?:pub(?:\([^)]*\))?\s+)?(?:unsafe\s+|async\s+|const\s+|extern\s+\"C\"\s+)*"
    r"(struct|enum|fn|trait|type|const|static|mod|union|macro_rules!)\s*(\w+)"
)
FN = re.compile(r"^\s*(?:pub(?:\([^)]*\))?\s+)?(?:default\s+)?(?:const\s+|async\s+|unsafe\s+|extern\s+\"[^\"]*\"\s+)*fn\s+(\w+)")


FN_LINE = re.compile(r"(?m)^[ \t]*(?:pub(?:\([^)\n]*\))?[ \t]+)?(?:default[ \t]+)?(?:(?:const|async|unsafe)[ \t]+|extern[ \t]+\"[^\"\n]*\"[ \t]+)*fn[ \t]+(\w+)")
RAW = re.compile(r'r(#*)"')
CHAR = re.compile(r"'(\\.[^']*|[^\\'])'")


def strip(text):
    """The text with comments, string and char literals blanked (newlines kept), so braces and
    paths can be matched with regular expressions."""
    out, i, n = [], 0, len(text)
    while i < n:
        c = text[i]
        if text.startswith("//", i):
            j = text.find("\n", i)
            j = n if j < 0 else j
            out.append(" " * (j - i))
            i = j
        elif text.startswith("/*", i):
            depth, j = 1, i + 2
            while j < n and depth:
                if text.startswith("/*", j):
                    depth, j = depth + 1, j + 2
                elif text.startswith("*/", j):
                    depth, j = depth - 1, j + 2
                else:
                    j += 1
            out.append(re.sub(r"[^\n]", " ", text[i:j]))
            i = j
        elif c == "r" and RAW.match(text, i) and (i == 0 or not (text[i - 1].isalnum() or text[i - 1] == "_")):
            m = RAW.match(text, i)
            close = '"' + m.group(1)
            j = text.find(close, i + len(m.group(0)))
            j = n if j < 0 else j + len(close)
            out.append('""' + re.sub(r"[^\n]", " ", text[i + 2:j]))
            i = j
        elif c == '"':
            j = i + 1
            while j < n and text[j] != '"':
                j += 2 if text[j] == "\\" else 1
            out.append('"' + re.sub(r"[^\n]", " ", text[i + 1:j]) + '"')
            i = j + 1
        elif c == "'":
            m = CHAR.match(text, i)
            if m:
                out.append(" " * len(m.group(0)))
                i += len(m.group(0))
            else:  # a lifetime
                out.append(c)
                i += 1
        else:
            out.append(c)
            i += 1
    return "".join(out)


def matching_brace(code, open_at):
    depth = 0
    for j in range(open_at, len(code)):
        if code[j] == "{":
            depth += 1
        elif code[j] == "}":
            depth -= 1
            if depth == 0:
                return j
    return len(code) - 1


def without_test_modules(code):
    """`code` with every `#[cfg(test)]` item (a test module) blanked."""
    for m in reversed(list(re.finditer(r"#\[cfg\(test\)\]\s*(?:pub\s+)?mod\s+\w+\s*\{", code))):
        end = matching_brace(code, m.end() - 1)
        code = code[:m.start()] + re.sub(r"[^\n]", " ", code[m.start():end + 1]) + code[end + 1:]
    return code


def long_functions(path, code):
    lines = code.count("\n")
    found = []
    for m in FN_LINE.finditer(code):
        # the body: the first `{` after the signature, unless a `;` comes first (no body)
        k = m.end()
        depth = 0
        while k < len(code):
            ch = code[k]
            if ch in "(<[":
                depth += 1
            elif ch in ")>]":
                depth = max(0, depth - 1)
            elif ch == ";" and depth == 0:
                k = -1
                break
            elif ch == "{" and depth == 0:
                break
            k += 1
        if k < 0 or k >= len(code):
            continue
        end = matching_brace(code, k)
        first = code.count("\n", 0, m.start()) + 1
        last = code.count("\n", 0, end) + 1
        found.append((last - first + 1, path, first, m.group(1)))
    del lines
    return found


def module_files(src):
    """{module path tuple: file} for one crate's `src` folder."""
    mods = {}
    for f in src.rglob("*.rs"):
        rel = f.relative_to(src).with_suffix("").parts
        if rel in (("lib",), ("main",)):
            key = ()
        elif rel[-1] == "mod":
            key = rel[:-1]
        elif rel[0] == "bin":
            continue
        else:
            key = rel
        mods[key] = f
    return mods


def expand_use(tree):
    """`a::{b, c::{d, e}}` → ['a::b', 'a::c::d', 'a::c::e']."""
    tree = re.sub(r"\s+", "", tree)
    if "{" not in tree:
        return [tree]
    i = tree.index("{")
    head, body = tree[:i], tree[i + 1:matching_brace(tree, i)]
    parts, depth, cur = [], 0, ""
    for ch in body:
        if ch == "," and depth == 0:
            parts.append(cur)
            cur = ""
            continue
        depth += ch == "{"
        depth -= ch == "}"
        cur += ch
    parts.append(cur)
    return [head + p2 for p in parts if p for p2 in expand_use(p)]


def crate_graph(src):
    mods = module_files(src)
    codes = {k: without_test_modules(strip(f.read_text())) for k, f in mods.items()}
    # top-level definitions only: ITEM at column 0 (methods and nested items are indented)
    defined = {}
    for k, c in codes.items():
        names = set()
        for line in c.splitlines():
            m = ITEM.match(line)
            if m:
                names.add(m.group(2))
        defined[k] = names
    reexports = defaultdict(dict)  # module -> {name: absolute path}
    uses = defaultdict(list)  # module -> [absolute path]

    def absolute(mod, path):
        segs = path.split("::")
        if segs[0] == "crate":
            base, segs = (), segs[1:]
        elif segs[0] == "self":
            base, segs = mod, segs[1:]
        elif segs[0] == "super":
            base = mod
            while segs and segs[0] == "super":
                base, segs = base[:-1], segs[1:]
        elif mod + (segs[0],) in mods:
            base = mod
        else:
            return None  # another crate or std
        return base + tuple(s for s in segs if s)

    for k, c in codes.items():
        for m in re.finditer(r"(?m)^\s*(pub(?:\([^)]*\))?\s+)?use\s+([^;]+);", c):
            for p in expand_use(m.group(2)):
                p = p.split("as")[0] if "::" in p and re.search(r"\bas\b", p) else p
                p = re.sub(r"\bas\w+$", "", p)
                a = absolute(k, p)
                if a is None:
                    continue
                if m.group(1) and m.group(1).startswith("pub") and "(" not in m.group(1):
                    reexports[k][a[-1]] = a
                else:
                    uses[k].append(a)
        for m in re.finditer(r"\b((?:crate|super)(?:::\w+)+)", c):
            line_start = c.rfind("\n", 0, m.start()) + 1
            if re.match(r"\s*(pub(\([^)]*\))?\s+)?use\b", c[line_start:m.start()]):
                continue
            a = absolute(k, m.group(1))
            if a is not None:
                uses[k].append(a)

    def resolve(a, seen=0):
        """The module that defines the item at absolute path `a`."""
        if seen > 10:
            return None
        for cut in range(len(a), -1, -1):
            mod = a[:cut]
            if mod in mods:
                rest = a[cut:]
                if not rest or rest[0] == "*":
                    return mod
                name = rest[0]
                if name in defined[mod]:
                    return mod
                if name in reexports[mod]:
                    return resolve(reexports[mod][name], seen + 1)
                for target in reexports[mod].values():
                    if target[-1] == "*":
                        r = resolve(target[:-1] + (name,), seen + 1)
                        if r is not None:
                            return r
                return mod
        return None

    edges = defaultdict(set)
    for k, paths in uses.items():
        for a in paths:
            r = resolve(a)
            if r is not None and r != k:
                edges[k].add(r)
    return mods, edges


def circles(mods, edges):
    index, low, stack, on, out, counter = {}, {}, [], set(), [], [0]

    def visit(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in edges.get(v, ()):
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
            if len(comp) > 1:
                out.append(comp)

    sys.setrecursionlimit(10000)
    for v in sorted(mods):
        if v not in index:
            visit(v)
    return out


def main():
    check = "--check" in sys.argv
    top = int(sys.argv[sys.argv.index("--top") + 1]) if "--top" in sys.argv else 0
    problems = 0
    for crate in sorted((ROOT / "crates").iterdir()):
        src = crate / "src"
        if not src.is_dir():
            continue
        mods, edges = crate_graph(src)
        for comp in circles(mods, edges):
            problems += 1
            files = sorted(str(mods[m].relative_to(ROOT)) for m in comp)
            print(f"circle in {crate.name}: " + " <-> ".join(files))
            for m in sorted(comp):
                inside = sorted(str(mods[w].relative_to(src)) for w in edges[m] if w in comp)
                print(f"    {mods[m].relative_to(src)} uses {', '.join(inside)}")
    funcs = []
    roots = [ROOT / "benches"] + [d for c in (ROOT / "crates").iterdir()
                                  for d in (c / "src", c / "tests", c / "examples", c / "benches")]
    for root in roots:
        if root.is_dir():
            for f in sorted(root.rglob("*.rs")):
                funcs += long_functions(f.relative_to(ROOT), strip(f.read_text()))
    funcs.sort(key=lambda t: (-t[0], str(t[1]), t[2]))
    for length, path, line, name in funcs:
        if length > LIMIT:
            problems += 1
            print(f"long function: {path}:{line} `{name}` is {length} lines (limit {LIMIT})")
    if top:
        print(f"-- the {top} longest functions")
        for length, path, line, name in funcs[:top]:
            print(f"{length:5} {path}:{line} {name}")
    if problems == 0:
        print(f"no file-level import circles, no function over {LIMIT} lines")
    return 1 if (check and problems) else 0


if __name__ == "__main__":
    sys.exit(main())
