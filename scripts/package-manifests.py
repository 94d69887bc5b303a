#!/usr/bin/env python3
"""Keep every crate of the workspace packageable (issue 23): one mechanical pass over the manifests.

For each workspace member `crates/*/Cargo.toml` (and `benches/Cargo.toml`, which is never
published) it makes sure the `[package]` table inherits the shared metadata of the root
`[workspace.package]` (`repository`, `keywords`, `categories`, `publish`) and names its
`readme = "README.md"` (the file must exist: a short README with a compiling example, included
as the crate's rustdoc front page), and that a `[package.metadata.docs.rs]` table exists. In
the root manifest every internal `vatcal-*` path dependency of `[workspace.dependencies]`
carries `version = "<workspace version>"` (`cargo package` needs a version on path
dependencies).

Idempotent: a second run changes nothing. Run it after adding (or merging) a crate, then write
its README.md; `--check` exits 1 and names what is missing (CI runs it). Only lines are added or
rewritten in place; nothing else in a manifest is touched.
"""

import argparse
import re
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
INHERITED = ["repository", "keywords", "categories"]
DOCS_RS = '[package.metadata.docs.rs]\nall-features = true\nrustdoc-args = ["--cfg", "docsrs"]\n'


def members() -> list[Path]:
    text = (ROOT / "Cargo.toml").read_text()
    block = re.search(r"^members\s*=\s*\[(.*?)\]", text, re.S | re.M)
    if not block:
        sys.exit("Cargo.toml: no workspace members")
    return [ROOT / m for m in re.findall(r'"([^"]+)"', block.group(1))]


def package_table_end(lines: list[str]) -> int:
    """Index of the first line after the [package] table's last key line."""
    start = lines.index("[package]")
    end = start + 1
    while end < len(lines) and not lines[end].startswith("["):
        end += 1
    while end > start + 1 and lines[end - 1].strip() == "":
        end -= 1
    return end


def fix_member(path: Path, problems: list[str]) -> str:
    manifest = path / "Cargo.toml"
    text = manifest.read_text()
    lines = text.split("\n")
    keys = {l.split("=")[0].split(".")[0].strip() for l in lines[lines.index("[package]") + 1 : package_table_end(lines)]}
    bench = path.name == "benches"
    add = []
    for key in INHERITED:
        if key not in keys:
            add.append(f"{key}.workspace = true")
    if not bench and "readme" not in keys:
        add.append('readme = "README.md"')
    if bench and "publish" in keys:
        lines = [("publish = false" if l.startswith("publish") else l) for l in lines]
    if add:
        problems.append(f"{manifest.relative_to(ROOT)}: [package] lacks {', '.join(add)}")
        end = package_table_end(lines)
        lines[end:end] = add
    text = "\n".join(lines)
    if not bench and "[package.metadata.docs.rs]" not in text:
        problems.append(f"{manifest.relative_to(ROOT)}: no [package.metadata.docs.rs]")
        lines = text.split("\n")
        end = package_table_end(lines)
        lines[end:end] = [""] + DOCS_RS.rstrip("\n").split("\n")
        text = "\n".join(lines)
    if not bench and not (path / "README.md").exists():
        problems.append(f"{path.relative_to(ROOT)}/README.md is missing (write one with a compiling example)")
    return text


def fix_root(problems: list[str]) -> str:
    manifest = ROOT / "Cargo.toml"
    text = manifest.read_text()
    version = re.search(r'^\[workspace\.package\]\n(?:.*\n)*?version\s*=\s*"([^"]+)"', text, re.M).group(1)

    def versioned(m: re.Match) -> str:
        name, body = m.group(1), m.group(2)
        if "version" in body:
            return m.group(0)
        problems.append(f"Cargo.toml: [workspace.dependencies] {name} has no version")
        return f'{name} = {{ {body.strip()}, version = "{version}" }}'

    return re.sub(r'^(vatcal-[a-z0-9-]+) = \{ (path = "[^"]+"[^}]*)\}', versioned, text, flags=re.M)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--check", action="store_true", help="change nothing; exit 1 when a manifest needs a fix")
    args = ap.parse_args()
    problems: list[str] = []
    updates = {ROOT / "Cargo.toml": fix_root(problems)}
    for m in members():
        updates[m / "Cargo.toml"] = fix_member(m, problems)
    if args.check:
        for p in problems:
            print(p, file=sys.stderr)
        return 1 if problems else 0
    for path, text in updates.items():
        if path.read_text() != text:
            path.write_text(text)
            print(f"write {path.relative_to(ROOT)}")
    for p in problems:
        if "README.md" in p:
            print(p, file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
