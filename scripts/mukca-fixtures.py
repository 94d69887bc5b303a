#!/usr/bin/env python3
"""Builds fixtures/real/mukca/ from a clone of github.com/platonics-delft/kinematics_calibration.

Usage: scripts/mukca-fixtures.py GIT_DIR [COMMIT]

Each placement's hole_0.csv / hole_1.csv (joint angles in radians, no header) becomes one file
<set>/<placement>.csv with the header position,tcp,q1..qN: position 1 = socket 0 (hole_0),
position 2 = socket 1 (hole_1), tcp 1 = the sphere; the joint values are copied verbatim
(radians: read them with --angle-unit rad). The URDFs are copied unchanged.
"""
import subprocess
import sys
from pathlib import Path

SETS = {
    # set: placements (the authors' data/<set>/<placement>/)
    "panda_6": ["front", "left", "right"],
    "panda_7": ["front", "right"],
    "kuka_14": ["front", "left_back", "raised_left"],
    "dinova_2": ["front", "left", "right-high"],  # front_rotated: the tool fell off mid-recording (its comments.txt)
}
URDFS = {
    "urdf/panda.urdf": "urdf/panda.urdf",
    "urdf/iiwa14.urdf": "urdf/iiwa14.urdf",
    "urdf/gen3lite.urdf": "urdf/gen3lite.urdf",
    "calibrated_urdf/panda_6/panda.urdf": "urdf/authors-calibrated/panda_6.urdf",
    "calibrated_urdf/panda_7/panda.urdf": "urdf/authors-calibrated/panda_7.urdf",
}


def show(git_dir, commit, path):
    return subprocess.run(
        ["git", "--git-dir", git_dir, "show", f"{commit}:{path}"], check=True, capture_output=True, text=True
    ).stdout


def main():
    git_dir = sys.argv[1]
    commit = sys.argv[2] if len(sys.argv) > 2 else "HEAD"
    out = Path(__file__).resolve().parent.parent / "fixtures" / "real" / "mukca"
    for name, placements in SETS.items():
        for placement in placements:
            rows = []
            for position, hole in ((1, "hole_0"), (2, "hole_1")):
                text = show(git_dir, commit, f"data/{name}/{placement}/{hole}.csv")
                for line in text.splitlines():
                    if line.strip():
                        rows.append(f"{position},1,{line.strip()}")
            n = len(rows[0].split(",")) - 2
            header = "position,tcp," + ",".join(f"q{i}" for i in range(1, n + 1))
            target = out / name / f"{placement}.csv"
            target.parent.mkdir(parents=True, exist_ok=True)
            target.write_text(
                f"# MUKCa {name}/{placement}: joint angles [rad]; position 1 = socket 0 (hole_0.csv), "
                f"2 = socket 1 (hole_1.csv), 50 mm apart\n{header}\n" + "\n".join(rows) + "\n"
            )
    for src, dst in URDFS.items():
        target = out / dst
        target.parent.mkdir(parents=True, exist_ok=True)
        target.write_text(show(git_dir, commit, src))


if __name__ == "__main__":
    main()
