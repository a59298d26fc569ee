"""List modules over 500 lines and functions over 80 lines (issue 11's size limits).

Usage, from the repository's root: ``python scripts/sizes.py [--modules 500] [--functions 80]``.
"""

from __future__ import annotations

import argparse
import ast
from pathlib import Path

PACKAGES = ("gcs_ppf", "sitl", "api")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--modules", type=int, default=500)
    ap.add_argument("--functions", type=int, default=80)
    args = ap.parse_args()
    for path in sorted(p for pkg in PACKAGES for p in Path(pkg).rglob("*.py")):
        source = path.read_text()
        n = source.count("\n")
        if n > args.modules:
            print(f"module   {n:5d}  {path}")
        for node in ast.walk(ast.parse(source)):
            if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
                length = (node.end_lineno or node.lineno) - node.lineno + 1
                if length > args.functions:
                    print(f"function {length:5d}  {path}:{node.lineno} {node.name}")


if __name__ == "__main__":
    main()
