"""Table I of paper 000 beside this project's measurements: markdown and a plot for `gnpp bench`.

The paper's figures (CPU seconds, mean and standard deviation over 10 seeds, one core of an
i7-1165G7, 100 s limit; `None` where the paper reports a failure "-") are transcribed from the
text rendering of its Table I, whose cells run mean and deviation together (`22.79.2` = 22.7 ±
9.2; both have one decimal in the time columns, so the reading is unambiguous). A measured
problem is matched to a paper problem by name (`lab4`, `Lab_4`, `lab4_paper` -> `Lab_4`); its N0 and
N are printed beside the paper's, so a problem smaller than the paper's is visible as such.
"""
from __future__ import annotations

import re
from typing import Iterable, Sequence

from gnppdsl.cli.algorithms import AlgorithmSpec

# problem -> (N0, N)
PAPER_LENGTHS: dict[str, tuple[int, int]] = {
    "Work_1": (2, 4), "Work_2": (4, 6), "Work_3": (4, 6), "Work_4": (8, 10), "Work_5": (8, 11),
    "Lab_1": (2, 3), "Lab_2": (2, 3), "Lab_3": (4, 5), "Lab_4": (4, 9), "Lab_5": (12, 17),
    "Field_1": (2, 4), "Field_2": (2, 6), "Field_3": (4, 8), "Field_4": (6, 10), "Field_5": (6, 11),
}
_ALGOS = ("oneway", "mbts", "gnpp_t", "gnpp_tr", "gnpp_trn", "gnpp_trng")
_ROWS = """
Work_1  8.2 1.0  23.5 4.4  5.7 1.2  5.7 1.3  5.6 0.9  5.3 0.1
Work_2  -        -         -        22.7 9.2  19.7 6.0  16.7 2.9
Work_3  -        -         -        19.1 5.3  22.1 5.9  21.4 6.1
Work_4  -        -         -        53.1 5.6  56.4 7.6  55.4 9.0
Work_5  -        -         -        -         76.0 7.0  76.8 9.4
Lab_1   7.1 1.0  4.1 0.5   4.5 0.2  3.2 0.2  3.3 0.1  3.3 0.2
Lab_2   3.1 0.5  3.7 0.5   5.5 0.3  4.3 0.2  2.1 0.1  2.1 0.1
Lab_3   8.4 1.2  18.5 2.7  5.9 0.4  3.1 0.2  3.3 0.4  3.2 0.2
Lab_4   -        -         -        -         6.5 0.6  6.3 0.4
Lab_5   -        -         -        18.7 1.8  19.1 2.0  19.0 2.0
Field_1 7.0 2.0  15.3 3.1  5.7 1.1  2.9 1.4  2.6 0.3  3.1 1.0
Field_2 -        -         -        6.1 0.4  6.3 0.5  6.3 0.5
Field_3 -        -         -        11.7 1.2  12.3 1.4  11.7 0.7
Field_4 -        -         -        13.2 1.5  13.6 1.6  13.5 1.3
Field_5 -        -         -        56.5 6.6  50.7 5.5  51.4 6.6
"""


def _parse_rows(text: str) -> dict[str, dict[str, tuple[float, float] | None]]:
    table: dict[str, dict[str, tuple[float, float] | None]] = {}
    for line in filter(None, (ln.strip() for ln in text.splitlines())):
        name, *cells = line.split()
        values: list[tuple[float, float] | None] = []
        while cells:
            if cells[0] == "-":
                values.append(None)
                cells = cells[1:]
            else:
                values.append((float(cells[0]), float(cells[1])))
                cells = cells[2:]
        assert len(values) == len(_ALGOS), name
        table[name] = dict(zip(_ALGOS, values))
    return table


PAPER_CPU = _parse_rows(_ROWS)


def paper_name(problem: str) -> str | None:
    """The paper's name of a measured problem (`lab4` -> `Lab_4`), None if it has none."""
    m = re.fullmatch(r"(work|lab|field)_?(\d)(?:_paper)?", problem.strip().lower())
    if not m:
        return None
    name = f"{m.group(1).capitalize()}_{m.group(2)}"
    return name if name in PAPER_LENGTHS else None


def _mean_std(xs: Sequence[float]) -> tuple[float, float] | None:
    if not xs:
        return None
    m = sum(xs) / len(xs)
    s = (sum((x - m) ** 2 for x in xs) / (len(xs) - 1)) ** 0.5 if len(xs) > 1 else 0.0
    return m, s


def measured_cpu(rows: Iterable[dict], problem: str, label: str) -> tuple[tuple[float, float] | None, int, int]:
    """(mean, std) CPU seconds of the solved runs, solved count, run count."""
    rs = [r for r in rows if r["problem"] == problem and r["algorithm"] == label]
    ok = [float(r["cpu_time"]) for r in rs if r["solved"]]
    return _mean_std(ok), len(ok), len(rs)


def _fmt(ms: tuple[float, float] | None) -> str:
    return "–" if ms is None else f"{ms[0]:.1f} ± {ms[1]:.1f}"


def markdown(problems: Sequence[str], specs: Sequence[AlgorithmSpec], rows: Sequence[dict]) -> str:
    """Table I as measured, the paper's CPU time in the column beside each algorithm."""
    head = ["problem", "N0 / N", "paper N0 / N"]
    for s in specs:
        head += [f"{s.title} cpu [s]", "solved", "paper"]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for p in problems:
        runs = [r for r in rows if r["problem"] == p]
        n0 = sorted({r["N0"] for r in runs if r.get("N0") not in (None, "")})
        n = sorted({r["N"] for r in runs if r.get("N") not in (None, "")})
        ref = paper_name(p)
        cells = [p, f"{'/'.join(map(str, n0)) or '–'} / {'/'.join(map(str, n)) or '–'}",
                 "%d / %d" % PAPER_LENGTHS[ref] if ref else ""]
        for s in specs:
            ms, ok, total = measured_cpu(rows, p, s.label)
            key = s.label.lower().replace("-", "_")
            paper = PAPER_CPU[ref].get("oneway" if key in ("oneway", "one_way") else key) if ref else None
            cells += [_fmt(ms), f"{ok}/{total}", _fmt(paper) if ref else ""]
        lines.append("| " + " | ".join(cells) + " |")
    lines.append("")
    lines.append("CPU seconds, mean ± standard deviation over the solved runs of this machine; "
                 "paper: Table I of paper 000 (one core of an i7-1165G7, 10 seeds, 100 s limit; "
                 "– where it reports no solution).")
    return "\n".join(lines) + "\n"


def plot(problems: Sequence[str], specs: Sequence[AlgorithmSpec], rows: Sequence[dict], path: str) -> None:
    """Bars of CPU time per problem: each algorithm measured here beside the paper's figure."""
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        from gnppdsl.errors import UserError
        raise UserError("--plot needs matplotlib: pip install 'gnppdsl[bench]' (or: pip install matplotlib)") from None
    width = 0.8 / max(1, 2 * len(specs))
    fig, ax = plt.subplots(figsize=(max(6.0, 1.2 * len(problems) * max(1, len(specs))), 4.0))
    for k, s in enumerate(specs):
        ours = [measured_cpu(rows, p, s.label)[0] for p in problems]
        key = s.label.lower().replace("-", "_")
        paper = [PAPER_CPU[paper_name(p)].get(key) if paper_name(p) else None for p in problems]
        xs = [i + (2 * k) * width for i in range(len(problems))]
        ax.bar(xs, [m[0] if m else 0 for m in ours], width, yerr=[m[1] if m else 0 for m in ours],
               label=f"{s.title} (this project)")
        ax.bar([x + width for x in xs], [m[0] if m else 0 for m in paper], width, hatch="//",
               yerr=[m[1] if m else 0 for m in paper], label=f"{s.title} (paper)", alpha=0.6)
    ax.set_xticks([i + (len(specs) - 0.5) * width for i in range(len(problems))])
    ax.set_xticklabels(problems, rotation=30, ha="right")
    ax.set_ylabel("CPU time [s]")
    ax.set_title("Table I: CPU time per problem")
    ax.legend(fontsize="small")
    fig.tight_layout()
    from gnppdsl.outputs import atomic_open

    with atomic_open(path, "--plot", binary=True) as fh:     # never through a symbolic link
        fig.savefig(fh, format="png", dpi=110)
    plt.close(fig)
