#!/usr/bin/env python3
"""Repository checks that keep the tree easy to enter (CONTRIBUTING.md, "Checks").

    .ci/checks.py            run every check; exit 1 on any failure
    .ci/checks.py --self-test

* README.md has at most 300 lines.
* No date (2026-11-28) and no issue, stop or pull-request number ("issue 12", "#12",
  "stop 34") in crates/*/src, crates/*/tests, src/ or tests/: code cites a decision record
  (docs/decisions/) or a paper.
* No import circle between the modules of a crate: module A uses B (directly or through
  others) and B uses A. The graph is read from `crate::` and `super::` paths and from
  `use` items; a folder module counts as one node, and its files form their own graph.
* No file in crates/*/src over 900 lines, and no non-test function over 150 lines.
"""
import os
import re
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
README_MAX = 300
FILE_MAX = 900
FN_MAX = 150

DATE = re.compile(r"\b20\d\d-[01]\d-[0-3]\d\b")
NUMBER = re.compile(
    r"(?i)\b(?:issues?|stops?|pr|pull request)\s+#?\d+\b|\(#\d+\)|\bsee #\d+\b"
)


def rust_files(*tops):
    for top in tops:
        base = os.path.join(ROOT, top)
        for dirpath, dirnames, filenames in os.walk(base):
            dirnames[:] = [d for d in dirnames if d not in ("target", ".venv")]
            for f in filenames:
                if f.endswith(".rs"):
                    yield os.path.join(dirpath, f)


def crate_dirs():
    crates = os.path.join(ROOT, "crates")
    return sorted(os.path.join(crates, d) for d in os.listdir(crates)
                  if os.path.isfile(os.path.join(crates, d, "Cargo.toml")))


def strip(src):
    """The source with comments and string/char literals blanked (newlines kept)."""
    out = []
    i, n = 0, len(src)
    while i < n:
        c = src[i]
        if src.startswith("//", i):
            j = src.find("\n", i)
            j = n if j < 0 else j
            out.append(" " * (j - i))
            i = j
        elif src.startswith("/*", i):
            depth, j = 1, i + 2
            while j < n and depth:
                if src.startswith("/*", j):
                    depth, j = depth + 1, j + 2
                elif src.startswith("*/", j):
                    depth, j = depth - 1, j + 2
                else:
                    j += 1
            out.append(re.sub(r"[^\n]", " ", src[i:j]))
            i = j
        elif c == "r" and re.match(r'r#*"', src[i:i + 12]) and (i == 0 or not (src[i - 1].isalnum() or src[i - 1] == "_")):
            m = re.match(r'r(#*)"', src[i:])
            end = '"' + m.group(1)
            j = src.find(end, i + len(m.group(0)))
            j = n if j < 0 else j + len(end)
            out.append(re.sub(r"[^\n]", " ", src[i:j]))
            i = j
        elif c == '"':
            j = i + 1
            while j < n and src[j] != '"':
                j += 2 if src[j] == "\\" else 1
            j += 1
            out.append(re.sub(r"[^\n]", " ", src[i:j]))
            i = j
        elif c == "'" and re.match(r"'(\\.|[^\\'])'|'\\u\{[0-9a-fA-F]+\}'|'\\x[0-9a-fA-F]{2}'", src[i:i + 12]):
            m = re.match(r"'(\\.|[^\\'])'|'\\u\{[0-9a-fA-F]+\}'|'\\x[0-9a-fA-F]{2}'", src[i:i + 12])
            out.append(" " * len(m.group(0)))
            i += len(m.group(0))
        else:
            out.append(c)
            i += 1
    return "".join(out)


def rel(path):
    return os.path.relpath(path, ROOT)


def check_readme():
    path = os.path.join(ROOT, "README.md")
    n = len(open(path, encoding="utf-8").read().splitlines())
    return [] if n <= README_MAX else [f"README.md: {n} lines (at most {README_MAX})"]


def check_history(files):
    errors = []
    for path in files:
        for no, line in enumerate(open(path, encoding="utf-8"), 1):
            for rx, what in ((DATE, "a date"), (NUMBER, "an issue or stop number")):
                m = rx.search(line)
                if m:
                    errors.append(f"{rel(path)}:{no}: {what} ({m.group(0)!r}); cite a decision record or a paper")
    return errors


def matching_brace(text, open_at):
    depth = 0
    for j in range(open_at, len(text)):
        if text[j] == "{":
            depth += 1
        elif text[j] == "}":
            depth -= 1
            if depth == 0:
                return j
    return len(text) - 1


def test_spans(text):
    """Character spans of `#[cfg(test)]` items and `#[test]` functions."""
    spans = []
    for m in re.finditer(r"#\[(?:cfg\(test\)|test)\]", text):
        brace = text.find("{", m.end())
        semi = text.find(";", m.end())
        if brace < 0 or (0 <= semi < brace):
            continue
        spans.append((m.start(), matching_brace(text, brace)))
    return spans


FN = re.compile(r"\bfn\s+([A-Za-z_]\w*)")


def long_functions(path, text):
    """(name, first line, lines) of each non-test function over FN_MAX lines."""
    out = []
    skip = test_spans(text)
    for m in FN.finditer(text):
        if any(a <= m.start() <= b for a, b in skip):
            continue
        # The body starts at the first `{` after the signature; a `;` first means no body.
        depth, j = 0, m.end()
        while j < len(text):
            ch = text[j]
            if ch in "([<":
                depth += 1
            elif ch in ")]>" and depth:
                depth -= 1
            elif ch == ";" and depth == 0:
                j = -1
                break
            elif ch == "{" and depth == 0:
                break
            j += 1
        if j < 0 or j >= len(text):
            continue
        end = matching_brace(text, j)
        first = text.count("\n", 0, m.start()) + 1
        last = text.count("\n", 0, end) + 1
        if last - first + 1 > FN_MAX:
            out.append((m.group(1), first, last - first + 1))
    return out


def check_sizes():
    errors = []
    for crate in crate_dirs():
        for path in rust_files(os.path.relpath(os.path.join(crate, "src"), ROOT)):
            src = open(path, encoding="utf-8").read()
            n = len(src.splitlines())
            if n > FILE_MAX:
                errors.append(f"{rel(path)}: {n} lines (at most {FILE_MAX} in crates/*/src)")
    for path in list(rust_files("src")) + [p for c in crate_dirs() for p in rust_files(rel(os.path.join(c, "src")))]:
        text = strip(open(path, encoding="utf-8").read())
        for name, line, n in long_functions(path, text):
            errors.append(f"{rel(path)}:{line}: fn {name} has {n} lines (at most {FN_MAX} outside tests)")
    return errors


# --- import circles -------------------------------------------------------------------

USE_GROUP = re.compile(r"\buse\s+(crate|super|self)::\{")
PATH = re.compile(r"\b(crate|super)((?:::[A-Za-z_]\w*)+)")


def module_files(src_dir):
    """{module path tuple: file} for every module file of a crate's src folder."""
    mods = {}
    for path in rust_files(rel(src_dir)):
        r = os.path.relpath(path, src_dir)[:-3].split(os.sep)
        if r[-1] in ("lib", "main") and len(r) == 1:
            r = []
        elif r[-1] == "mod":
            r = r[:-1]
        mods[tuple(r)] = path
    return mods


def references(module, text):
    """Module paths (tuples) that `text`, the source of `module`, names."""
    refs = []
    # Expand `use crate::{a, b::c}` one level: each member is a path of its own.
    for m in USE_GROUP.finditer(text):
        end = matching_brace(text, m.end() - 1)
        body = text[m.end():end]
        base = m.group(1)
        depth, item = 0, ""
        for ch in body + ",":
            if ch == "{":
                depth += 1
            elif ch == "}":
                depth -= 1
            if ch == "," and depth == 0:
                name = re.match(r"\s*([A-Za-z_]\w*(?:::[A-Za-z_]\w*)*)", item)
                if name:
                    refs.append(resolve(module, base, name.group(1).split("::")))
                item = ""
            else:
                item += ch
    for m in PATH.finditer(text):
        refs.append(resolve(module, m.group(1), m.group(2).strip(":").split("::")))
    return [r for r in refs if r is not None]


def resolve(module, base, parts):
    if base == "crate":
        return tuple(parts)
    if base == "self":
        return tuple(module) + tuple(parts)
    # `super` in a module file is its parent; `super::super::x` climbs further.
    here = list(module)[:-1]
    while parts and parts[0] == "super":
        here = here[:-1]
        parts = parts[1:]
    return tuple(here) + tuple(parts)


def cycles(graph):
    """Every strongly connected component with more than one node (Tarjan)."""
    index, low, on, stack, out = {}, {}, set(), [], []
    counter = [0]

    def visit(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in graph.get(v, ()):
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
                out.append(sorted(comp))

    sys.setrecursionlimit(10000)
    for v in sorted(graph):
        if v not in index:
            visit(v)
    return out


def module_graph(src_dir):
    """Edges between sibling modules: for each folder (the crate root included), which of
    its children uses which (a reference deeper in a sibling counts for that sibling)."""
    mods = module_files(src_dir)
    graph = {}
    for module, path in mods.items():
        if not module:
            continue  # the crate root declares and re-exports everything
        text = strip(open(path, encoding="utf-8").read())
        for spans in [test_spans(text)]:
            for a, b in reversed(spans):
                text = text[:a] + re.sub(r"[^\n]", " ", text[a:b + 1]) + text[b + 1:]
        for target in references(module, text):
            # The longest prefix of `target` that is a module.
            while target and target not in mods:
                target = target[:-1]
            if not target:
                continue
            # The deepest common folder; the edge joins its two children on each side.
            k = 0
            while k < min(len(module), len(target)) and module[k] == target[k]:
                k += 1
            if k >= len(module) or k >= len(target):
                continue  # a module and its own ancestor or descendant
            a, b = module[:k + 1], target[:k + 1]
            graph.setdefault(a, set()).add(b)
    return graph


def check_circles():
    errors = []
    dirs = [os.path.join(c, "src") for c in crate_dirs()] + [os.path.join(ROOT, "src")]
    for src_dir in dirs:
        for comp in cycles(module_graph(src_dir)):
            names = ", ".join("::".join(m) for m in comp)
            errors.append(f"{rel(src_dir)}: import circle between {names}")
    return errors


def self_test():
    import tempfile
    with tempfile.TemporaryDirectory() as d:
        os.makedirs(os.path.join(d, "a"))
        files = {
            "lib.rs": "pub mod a; pub mod b; pub mod c;",
            "a/mod.rs": "mod x; mod y; use crate::b::Thing;",
            "a/x.rs": "use super::y::Y; // crate::c::Z in a comment\n",
            "a/y.rs": 'use super::x::X; const S: &str = "crate::c::Z";',
            "b.rs": "pub struct Thing; fn f() { crate::c::g() }",
            "c.rs": "use crate::{a::x::X, d};\n#[cfg(test)]\nmod tests { use crate::b::Thing; }",
        }
        for name, text in files.items():
            with open(os.path.join(d, name), "w") as f:
                f.write(text)
        graph = module_graph(d)
        found = cycles(graph)
        assert [("a",), ("b",), ("c",)] in found, (graph, found)
        assert [("a", "x"), ("a", "y")] in found, (graph, found)
        # The test module's `use crate::b` does not make c -> b.
        assert ("b",) not in graph.get(("c",), set()), graph
    long_src = "fn f() {\n" + "    let x = 1;\n" * 160 + "}\n#[cfg(test)]\nmod tests {\n    fn g() {\n" + "    ;\n" * 200 + "}\n}\n"
    got = long_functions("x.rs", strip(long_src))
    assert [n for n, _, _ in got] == ["f"], got
    assert strip('let s = "{"; // }\n') == 'let s =    ;     \n'
    for bad in ("// since 2026-11-28", "// issue 12", "// see #42", "// stop 34", "// (#7)"):
        assert DATE.search(bad) or NUMBER.search(bad), bad
    for good in ("#[derive(Debug)]", "let x = a[#1];", "// 44.1 kHz", "// issue a warning",
                 'fill="#000"', "color: #888888"):
        assert not (DATE.search(good) or NUMBER.search(good)), good
    print("checks.py self-test passed")


def main():
    if sys.argv[1:] == ["--self-test"]:
        self_test()
        return 0
    history = list(rust_files("src", "tests")) + [
        p for c in crate_dirs() for top in ("src", "tests", "benches", "examples")
        for p in rust_files(rel(os.path.join(c, top)))
    ]
    groups = [
        ("README length", check_readme()),
        ("dates and issue numbers in code", check_history(history)),
        ("import circles", check_circles()),
        ("file and function sizes", check_sizes()),
    ]
    failed = False
    for name, errors in groups:
        print(f"{name}: {'ok' if not errors else f'{len(errors)} problem(s)'}")
        for e in errors:
            print(f"  {e}")
        failed |= bool(errors)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
