"""Progress bars of the servo loop that count what the summaries count.

A phase first holds the trajectory's start for ``n_settle`` cycles (logged as
``<phase>:settle``, left out of the phase's statistics), then follows it for ``n_traj`` cycles
(the ``cycles`` of the result). :class:`PhaseProgress` shows the two apart: ``<phase>: settling``
up to ``n_settle``, then ``<phase>`` up to ``n_traj``, so the bar ends on the summary's count.
"""

from __future__ import annotations

from tqdm import tqdm


class PhaseProgress:
    """One phase's bar: call :meth:`step` after every cycle, :meth:`close` at the end."""

    def __init__(self, phase: str, n_settle: int, n_traj: int, enabled: bool = True) -> None:
        self.phase = phase
        self.n_settle = max(0, int(n_settle))
        self.n_traj = int(n_traj)
        self._k = 0
        settling = self.n_settle > 0
        self.bar = tqdm(total=self.n_settle if settling else self.n_traj,
                        desc=f"{phase}: settling" if settling else phase,
                        unit="cyc", leave=False, disable=not enabled)

    def step(self) -> None:
        """One cycle done."""
        self._k += 1
        self.bar.update(1)
        if self._k == self.n_settle:  # the trajectory starts: count its cycles from zero
            self.bar.set_description(self.phase, refresh=False)
            self.bar.reset(total=self.n_traj)

    def close(self) -> None:
        """Show the final count, then remove the bar."""
        self.bar.refresh()
        self.bar.close()
