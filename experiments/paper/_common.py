"""Shared argument handling for the figure/table scripts: each reads collected results only."""
from __future__ import annotations

import argparse
import time
from pathlib import Path

import pandas as pd



def parse(description: str, default_name: str):
    ap = argparse.ArgumentParser(description=description)
    ap.add_argument("results", type=Path, help=f"collected results directory (holding {default_name}) or the file itself")
    ap.add_argument("--out", type=Path, default=None, help="output directory (default: RESULTS/figures)")
    args = ap.parse_args()
    src = args.results / default_name if args.results.is_dir() else args.results
    if not src.is_file():
        ap.error(f"{src}: not found (run the task that produces {default_name} first)")
    out = args.out or (src.parent / "figures")
    out.mkdir(parents=True, exist_ok=True)
    return src, out, time.perf_counter()


def done(out: Path, names: list[str], t0: float) -> None:
    print(f"wrote {', '.join(str(out / n) for n in names)} in {time.perf_counter() - t0:.2f} s")


def read_csv(path: Path) -> pd.DataFrame:
    return pd.read_csv(path)
