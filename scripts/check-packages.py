#!/usr/bin/env python3
"""Check that every crate of the workspace builds from its own package tarball (issue 23).

`cargo package --workspace` with verification builds each crate separately against its own
dependency resolution, so the registry crates are compiled again per feature set: on a 2-core
CI machine that alone takes longer than the whole test suite. This script does the same check
in one pass:

1. `cargo package --workspace --no-verify` writes `target/package/<crate>-<version>.crate`
   (manifest checks, file lists, README and `include_str!` sources inside the tarball);
2. every tarball is unpacked into `target/package-check/` and joined in a scratch workspace whose
   `[patch.crates-io]` points each `vatcal-*` dependency at its unpacked tarball (the published
   manifests name them by version only), with the workspace's `Cargo.lock`;
3. `cargo check --workspace --lib --bins` type-checks every crate from its tarball alone: a file
   left out of a package, or a dependency reached through the workspace only, fails here.

Usage: `python3 scripts/check-packages.py` (from anywhere in the repository).
"""
import glob
import os
import shutil
import subprocess
import sys
import tarfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
TARGET = os.environ.get("CARGO_TARGET_DIR", os.path.join(ROOT, "target"))
if not os.path.isabs(TARGET):
    TARGET = os.path.join(ROOT, TARGET)
PACKAGES = os.path.join(TARGET, "package")
SCRATCH = os.path.join(TARGET, "package-check")


def run(cmd, cwd):
    print("+", " ".join(cmd), flush=True)
    subprocess.run(cmd, cwd=cwd, check=True)


def profiles():
    """The `[profile.*]` tables of the workspace's Cargo.toml, verbatim."""
    with open(os.path.join(ROOT, "Cargo.toml")) as f:
        lines = f.read().splitlines()
    out, inside = [], False
    for line in lines:
        if line.startswith("["):
            inside = line.startswith("[profile.")
        if inside:
            out.append(line)
    return "\n".join(out) + "\n"


def main():
    for old in glob.glob(os.path.join(PACKAGES, "vatcal-*.crate")):
        os.remove(old)
    run(["cargo", "package", "--workspace", "--exclude", "vatcal-benches", "--no-verify",
         "--allow-dirty"], ROOT)
    crates = sorted(glob.glob(os.path.join(PACKAGES, "vatcal-*.crate")))
    if not crates:
        sys.exit("check-packages: cargo package wrote no vatcal-*.crate")
    shutil.rmtree(SCRATCH, ignore_errors=True)
    os.makedirs(SCRATCH)
    members, patches = [], []
    for crate in crates:
        with tarfile.open(crate, "r:gz") as tar:
            tar.extractall(SCRATCH, filter="data")
        folder = os.path.basename(crate)[: -len(".crate")]
        name = folder.rsplit("-", 1)[0]
        members.append(folder)
        patches.append(f'{name} = {{ path = "{folder}" }}')
    with open(os.path.join(SCRATCH, "Cargo.toml"), "w") as f:
        f.write("# scratch workspace of scripts/check-packages.py: the unpacked tarballs\n")
        f.write("[workspace]\nresolver = \"3\"\nmembers = [\n")
        f.writelines(f'    "{m}",\n' for m in members)
        f.write("]\n\n[patch.crates-io]\n")
        f.writelines(p + "\n" for p in patches)
        # the workspace's profiles, so the registry crates clippy and the tests checked are reused
        f.write("\n" + profiles())
    shutil.copy(os.path.join(ROOT, "Cargo.lock"), os.path.join(SCRATCH, "Cargo.lock"))
    run(["cargo", "check", "--workspace", "--lib", "--bins", "--target-dir", TARGET], SCRATCH)
    print(f"check-packages: {len(crates)} crates build from their own tarballs")


if __name__ == "__main__":
    main()
