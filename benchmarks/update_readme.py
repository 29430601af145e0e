"""Regenerate the README's results table(s) between ``<!-- results:NAME -->`` markers.

Run: ``python -m benchmarks.update_readme quick`` after
``python -m benchmarks --preset quick --out benchmarks/results/quick`` (``make bench``).
A name ``DIR/EXPERIMENT`` (markers ``<!-- results:full/dubins -->``) takes the table of one
experiment of ``benchmarks/results/DIR``; a bare ``DIR`` takes its first experiment.
"""

from __future__ import annotations

import argparse
import re
from pathlib import Path

from benchmarks.readme_table import readme_table

ROOT = Path(__file__).resolve().parent.parent


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("presets", nargs="+", help="report directories under "
                        "benchmarks/results, optionally DIR/EXPERIMENT")
    args = parser.parse_args()
    readme = ROOT / "README.md"
    text = readme.read_text()
    for name in args.presets:
        directory, _, experiment = name.partition("/")
        table = readme_table(ROOT / "benchmarks" / "results" / directory,
                             experiment or None).strip()
        pattern = re.compile(rf"(<!-- results:{re.escape(name)} -->\n).*?(<!-- /results:"
                             rf"{re.escape(name)} -->)", re.S)
        if not pattern.search(text):
            raise SystemExit(f"README has no <!-- results:{name} --> markers")
        text = pattern.sub(lambda m, t=table: m.group(1) + t + "\n" + m.group(2), text)
    readme.write_text(text)
    print(f"updated {readme}")


if __name__ == "__main__":
    main()
