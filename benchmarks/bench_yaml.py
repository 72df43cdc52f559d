"""YAML request bodies: time to decode one, warm children against a new interpreter each.

    python benchmarks/bench_yaml.py [--n 100]

Decodes each example robot config (``examples/robots/*.yaml``) and a 100 kB document ``n``
times through the API's decoder (:func:`pickstop.api.body.decode_yaml`: warm children,
:mod:`pickstop.runtime.yaml_decoders`) and through a new ``python -m pickstop.api.yaml_child``
per document (how every body was decoded before the children were kept warm). Prints the
median and p90 wall time per document, and the CPU the API's own thread spent.
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import time
from pathlib import Path

from pickstop.api.body import decode_yaml

ROBOTS = Path(__file__).parents[1] / "examples" / "robots"


def one_shot(raw: bytes) -> None:
    subprocess.run([sys.executable, "-m", "pickstop.api.yaml_child"], input=raw,
                   capture_output=True, timeout=5, check=True)  # fmt: skip


def timed(fn, raw: bytes, n: int) -> tuple[float, float, float]:
    walls, cpu0 = [], time.thread_time()
    for _ in range(n):
        t0 = time.perf_counter()
        fn(raw)
        walls.append(time.perf_counter() - t0)
    walls.sort()
    return statistics.median(walls), walls[int(0.9 * (n - 1))], (time.thread_time() - cpu0) / n


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=100)
    args = ap.parse_args()
    big = "items:\n" + "".join(f"  - {{a: {i}, b: [1, 2.5, x{i}], c: 's'}}\n" for i in range(2500))
    docs = {p.name: p.read_bytes() for p in sorted(ROBOTS.glob("*.yaml"))}
    docs["100 kB list"] = big.encode()
    decode_yaml(b"a: 1\n")  # the first child starts
    print(f"{'document':<16} {'bytes':>7}  {'warm child p50/p90 [ms]':>24}  "
          f"{'new interpreter p50/p90 [ms]':>29}  {'API thread CPU [ms]':>19}")  # fmt: skip
    for name, raw in docs.items():
        w50, w90, wcpu = timed(decode_yaml, raw, args.n)
        s50, s90, _ = timed(one_shot, raw, max(args.n // 5, 5))
        print(f"{name:<16} {len(raw):>7}  {w50 * 1e3:>11.1f} / {w90 * 1e3:>9.1f}  "
              f"{s50 * 1e3:>14.1f} / {s90 * 1e3:>11.1f}  {wcpu * 1e3:>19.2f}")  # fmt: skip


if __name__ == "__main__":
    main()
