"""A minimal progress bar: drawn on a terminal, silent when stderr is not a TTY."""

from __future__ import annotations

import sys
import time
from typing import TextIO


class Progress:
    """``with Progress(total, "dual") as p: p.update(1)``: done / total, the rate and the time
    left; ``unit`` names what is counted (``frames``, ``scenes``)."""

    def __init__(
        self,
        total: int,
        desc: str = "",
        enabled: bool | None = None,
        stream: TextIO | None = None,
        unit: str = "frames",
    ):
        self.unit = unit
        self.stream = stream or sys.stderr
        self.enabled = self.stream.isatty() if enabled is None else enabled
        self.total = max(total, 1)
        self.desc = desc
        self.n = 0
        self.t0 = time.perf_counter()
        self._last = 0.0
        self.postfix = ""

    def update(self, n: int = 1, **postfix: object) -> None:
        self.n += n
        if postfix:
            self.postfix = " ".join(f"{k}={v}" for k, v in postfix.items())
        if not self.enabled:
            return
        now = time.perf_counter()
        if now - self._last < 0.1 and self.n < self.total:
            return
        self._last = now
        self.stream.write("\r" + self.line(now) + "  ")
        self.stream.flush()

    def line(self, now: float | None = None) -> str:
        """The bar's text: done / total, the rate so far and the time left at that rate.

        Examples
        --------
        >>> p = Progress(200, "dual crossing2", enabled=False)
        >>> p.n, p.t0 = 50, 0.0
        >>> p.line(now=2.0)
        'dual crossing2 [#######---------------------] 50/200 25.0 frames/s, 0:06 left'
        """
        now = time.perf_counter() if now is None else now
        frac = min(self.n / self.total, 1.0)
        width = 28
        bar = "#" * int(frac * width) + "-" * (width - int(frac * width))
        rate = self.n / max(now - self.t0, 1e-9)
        left = (self.total - self.n) / rate if rate > 0 else 0.0
        eta = f"{int(left // 60)}:{int(left % 60):02d}"
        post = f" {self.postfix}" if self.postfix else ""
        return (
            f"{self.desc} [{bar}] {self.n}/{self.total} {rate:.1f} {self.unit}/s, {eta} left{post}"
        )

    def close(self) -> None:
        if self.enabled:
            self.stream.write("\n")
            self.stream.flush()

    def __enter__(self) -> Progress:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
