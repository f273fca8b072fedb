"""sweep.trial: which trials need the tracker's kernels warmed on the workers."""

from __future__ import annotations

from pathlib import Path

import pytest

from wristmark.sweep.spec import load_spec
from wristmark.sweep.trial import tracks_frames


@pytest.mark.parametrize(("args", "tracks"), [
    ((), True),  # the rig's sensor: vision unless its file says otherwise
    (("--sensor", "vision", "--duration", "2"), True),
    (("--duration", "2", "--sensor", "truth-noise"), False),
    (("--sensor=truth-noise",), False),
    (("--sensor",), True),  # malformed: the parser refuses it later; warming up is harmless
])
def test_only_truth_noise_trials_skip_the_trackers_warm_up(args: tuple[str, ...], tracks: bool) -> None:
    assert tracks_frames(args) is tracks


def test_the_words_of_a_spec_s_trials_say_truth_noise(tmp_path: Path) -> None:
    spec = tmp_path / "s.yaml"
    spec.write_text("experiment: cube\nset: {sensor: truth-noise, duration: 1.0}\ngrid: {latency: [0.0, 0.04]}\n")
    trials = load_spec(spec).trials
    assert len(trials) == 2 and not any(tracks_frames(t.args) for t in trials)
    spec.write_text("experiment: cube\nset: {duration: 1.0}\ngrid: {sensor: [vision, truth-noise]}\n")
    assert [tracks_frames(t.args) for t in load_spec(spec).trials] == [True, False]
