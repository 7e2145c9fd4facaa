"""Frame time stamps as the libraries take them: seconds since any origin, a finite float.

The detectors and the tracker check every stamp the same way and raise their own input
error (a ``ValueError`` subclass) naming the bad value.
"""

from __future__ import annotations

import math
from typing import Any


def checked_stamp(stamp: Any, error: type[ValueError] = ValueError) -> float:
    """``stamp`` as a float of seconds; ``error`` when it is not a number or not finite."""
    try:
        value = float(stamp)
    except (TypeError, ValueError) as exc:
        raise error(f"stamp {stamp!r} is not a number") from exc
    if not math.isfinite(value):
        raise error(f"stamp {stamp!r} is not finite")
    return value
