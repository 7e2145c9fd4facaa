"""How the bag modules report a bag they cannot use: :class:`BagError` and the ``on_error`` policy.

* :class:`BagError` -- raised by :mod:`~mk_tracker.bags.bag_io` (reading),
  :mod:`~mk_tracker.bags.bag_storage` (one storage file), :mod:`~mk_tracker.bags.bag_writer`
  and :mod:`~mk_tracker.bags.bag_typestore`; the message names the file and the problem.
* :data:`OnError` -- ``"raise"`` (any problem is a :class:`BagError`) or ``"skip"`` (read
  what is readable and list the problems), the reader's choice.

A module of its own so that the reader, the writer and the typestore share one error class
without importing each other.  Importers may keep taking both names from
:mod:`mk_tracker.bags.bag_io`.
"""

from __future__ import annotations

from typing import Literal

OnError = Literal["raise", "skip"]


class BagError(ValueError):
    """A bag cannot be written or read as a whole: names the file and the problem."""
