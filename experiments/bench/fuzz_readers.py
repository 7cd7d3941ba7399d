"""Fuzz the readers (docs/reliability.md): ``--cases N`` (default 2,000) mutated files per reader.

Readers: BVH, WAV, TextGrid, TSV, CSV, IBM JSON transcripts, corpus manifests (YAML, CSV) and GENEA
folders (convsynth_jax/testing/fuzz.py: seeds, mutations, outcome classes). Each case applies 1-3
random mutations (bytes cut, flipped or inserted, a line deleted or repeated, a number replaced by
NaN/inf/huge/negative/text; for corpora also a file removed) to one file and reads it. Reported per
reader: how many cases loaded, gave the project's error naming the file, gave the project's error
without the file's name, raised another exception, or took longer than 5 s; the slowest case; and
up to 5 examples of each defect. Writes experiments/results/fuzz_readers.json with its manifest.

    python experiments/bench/fuzz_readers.py [--cases N] [--seed S] [--readers bvh,wav,...]
"""
import argparse
import collections
import random
import sys
import tempfile
import time
from pathlib import Path


from convsynth_jax.testing.fuzz import KINDS, READERS, Mutation, run_case
from convsynth_jax.api import write_result

CORPORA = ("manifest_yaml", "manifest_csv", "genea")


def fuzz(reader: str, cases: int, rng: random.Random, seeds: Path, work: Path) -> dict:
    counts = collections.Counter()
    examples = collections.defaultdict(list)
    slowest = 0.0
    t0 = time.perf_counter()
    for _ in range(cases):
        muts = [Mutation(rng.choice(KINDS), rng.randrange(1 << 20), rng.randrange(1 << 10))
                for _ in range(rng.randint(1, 3))]
        file_index = rng.randrange(64)
        remove = reader in CORPORA and rng.random() < 0.1
        out = run_case(reader, seeds, work, muts, file_index, remove)
        counts[out.status] += 1
        slowest = max(slowest, out.seconds)
        if out.status not in ("loaded", "project_error") and len(examples[out.status]) < 5:
            examples[out.status].append({"mutations": [m.__dict__ for m in muts], "file_index": file_index,
                                         "remove": remove, "detail": out.detail[:300]})
    return {"cases": cases, **{k: counts.get(k, 0) for k in ("loaded", "project_error", "unnamed_error", "unexpected", "slow")},
            "slowest_s": round(slowest, 4), "seconds": round(time.perf_counter() - t0, 1), "examples": dict(examples)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", type=int, default=2000)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--readers", default=",".join(READERS))
    ap.add_argument("--no-write", action="store_true", help="print only (exploration)")
    args = ap.parse_args()
    rng = random.Random(args.seed)
    load_before = Path("/proc/loadavg").read_text().split()[:3]
    result = {"cases_per_reader": args.cases, "seed": args.seed, "readers": {}}
    with tempfile.TemporaryDirectory(prefix="fuzz_readers_") as tmp:
        seeds, work = Path(tmp) / "seeds", Path(tmp) / "work"
        for reader in args.readers.split(","):
            result["readers"][reader] = r = fuzz(reader, args.cases, rng, seeds, work)
            print(reader, {k: v for k, v in r.items() if k != "examples"}, file=sys.stderr)
    total = result["readers"].values()
    result["unexpected_total"] = sum(r["unexpected"] + r["unnamed_error"] for r in total)
    result["slow_total"] = sum(r["slow"] for r in total)
    result["loadavg_before"] = load_before
    result["loadavg_after"] = Path("/proc/loadavg").read_text().split()[:3]
    if args.no_write:
        import json

        print(json.dumps(result, indent=1))
    else:
        write_result("fuzz_readers", result, overrides=[f"--cases={args.cases}", f"--seed={args.seed}"])


if __name__ == "__main__":
    main()
