"""Algorithm labels of `gnpp bench` (`oneway`, `gnpp`, `gnpp_trn`, `rlgp_tr`...) and their titles.

Shared by the table (`bench`) and the runs (`sweep`), which name a run's algorithm by its label.
"""
from __future__ import annotations

import re
from dataclasses import dataclass

from gnppdsl.solve.result import algorithm_title   # light: no solver imports


@dataclass(frozen=True)
class AlgorithmSpec:
    label: str          # as given, e.g. "gnpp_trn"
    algorithm: str      # "gnpp" | "oneway" | "rlgp"
    switches: str | None

    @property
    def title(self) -> str:
        return algorithm_title(self.algorithm, self.switches)


def parse_algorithms(text: str) -> list[AlgorithmSpec]:
    from gnppdsl.errors import UserError

    specs = []
    for raw in (t.strip() for t in text.split(",")):
        if not raw:
            continue
        low = raw.lower().replace("-", "_")
        if low in ("oneway", "one_way"):
            specs.append(AlgorithmSpec(raw, "oneway", ""))
            continue
        m = re.fullmatch(r"(gnpp|rlgp)(?:_([trng]*))?", low)
        if not m or (m.group(2) is not None and len(set(m.group(2))) != len(m.group(2))):
            raise UserError(f"--algorithms: unknown algorithm '{raw}' "
                            f"(use oneway, gnpp, rlgp or gnpp_<subset of trng>, e.g. gnpp_trn)")
        specs.append(AlgorithmSpec(raw, m.group(1), m.group(2)))
    if not specs:
        raise UserError("--algorithms: no algorithm given")
    return specs
