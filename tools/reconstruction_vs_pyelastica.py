"""Print the table of backbone reconstructions from end poses against the rods relaxed by PyElastica.

For each case shipped in ``tests/data/pyelastica/`` (README there), the backbone is
reconstructed from the base pose, the tip pose and the length by the PH quintics, the
circular arc and the physics fits of :mod:`optikin.physics.comparison`, and the
largest and RMS node distances [mm] at matched arc lengths are printed as Markdown.

Run ``python tools/reconstruction_vs_pyelastica.py`` (reference: the Richardson
extrapolation of the 100- and 200-element shapes) or ``--elements 200`` (the raw
200-element shape, its tip frame the last element's).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from optikin.physics.comparison import METHODS, Comparator, markdown_table, pyelastica_rod

DATA = Path(__file__).resolve().parent.parent / "tests" / "data" / "pyelastica"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=DATA, help="folder of the <case>_n<N>.npz files")
    parser.add_argument("--elements", type=int, default=None, help="raw shape of N elements (default: extrapolated)")
    args = parser.parse_args()
    cases = sorted({p.name.rsplit("_n", 1)[0] for p in args.data.glob("*_n*.npz")})
    comparator = Comparator()
    comparisons = []
    for case in cases:
        files = {}
        for path in args.data.glob(f"{case}_n*.npz"):
            with np.load(path, allow_pickle=False) as d:
                files[int(d["n_elements"])] = {k: d[k] for k in d.files}
        comparisons.append(comparator.compare(pyelastica_rod(files, args.elements)))
    print(markdown_table(comparisons))
    print()
    print("| case | " + " | ".join(f"{m} [s]" for m in METHODS) + " |")
    print("|" + "---|" * (len(METHODS) + 1))
    for c in comparisons:
        seconds = " | ".join(f"{c.results[m].seconds:.3f}" for m in METHODS)
        print(f"| {c.rod.name} | {seconds} |")


if __name__ == "__main__":
    main()
