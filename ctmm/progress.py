"""Progress reporting for long runs: a tqdm bar on terminals, silent otherwise."""
from __future__ import annotations

import sys


class _Silent:
    def update(self, n: int = 1) -> None:
        pass

    def close(self) -> None:
        pass


def progress_bar(total: int, description: str, *, enabled: bool | None = None, min_total: int = 20000):
    """Return a progress bar for ``total`` steps.

    Parameters
    ----------
    total : int
        Number of steps.
    description : str
        Label shown left of the bar.
    enabled : bool, optional
        True/False to force; default: shown only when stderr is a terminal and ``total`` is at
        least ``min_total`` (tqdm's ``disable=None`` rule: quiet in CI and pipes).
    """
    if enabled is False or (enabled is None and (total < min_total or not sys.stderr.isatty())):
        return _Silent()
    from tqdm.auto import tqdm

    return tqdm(total=total, desc=description, disable=None if enabled is None else False,
                mininterval=0.5, leave=False)
