"""Truncation degree of the twin multipole expansions as a function of the gap.

Near contact the expansions about the two centres converge like ``exp(-k (L - 14) sqrt(r/a - 2))``
(``k ~ 1.5``), so the degree must grow like ``(r/a - 2)^(-1/2)`` (Jeffrey & Onishi 1984; docs/model.md
section 4). With ``L = ceil(14 + c/sqrt(r - 2))`` the pair functions change by less than 3e-6 U0 from
``c = 8`` to ``c = 10`` at every separation ``r >= 2.0001 a``, and by about 20x less from ``c = 10`` to
``c = 12`` (``scripts/generate_near_field_table.py --convergence``).
"""

from __future__ import annotations

import math
from typing import Final

DEFAULT_ORDER_CONSTANT: Final = 10.0
"""``c`` in ``L = 14 + c/sqrt(r - 2)``."""


def truncation_order(separation: float, constant: float = DEFAULT_ORDER_CONSTANT) -> int:
    """Truncation degree ``L = ceil(14 + constant/sqrt(r - 2))`` at centre distance ``r = separation``.

    Raises:
        ValueError: if ``separation <= 2``.
    """
    if not separation > 2.0:
        raise ValueError(f"separation must exceed 2, got {separation}")
    return int(math.ceil(14.0 + constant / math.sqrt(separation - 2.0)))
