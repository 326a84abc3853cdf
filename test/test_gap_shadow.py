"""One estimator: the gap diagnosis takes its posteriors from the same Shadow pipeline as replay.

On ``bags/demo_3d`` (the paper's +0.7 / -0.7 mm offset, sun-driven gradients, a test car):
``gap``'s ``before`` is exactly ``replay``'s posterior, its ``after`` (with the named thermal and
traffic effects added to the model) is the offset the twin put in, and the text and the report say
what each number is.
"""

from __future__ import annotations

import contextlib
import io
import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from bridge_shadow.cli import main


def _cli(argv: list[str]) -> str:
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        assert main(argv) == 0
    return out.getvalue()


@pytest.fixture(scope="module")
def demo(
    root: Path, tmp_path_factory: pytest.TempPathFactory
) -> tuple[dict[str, Any], dict[str, Any], Path, str]:
    """``gap --json --report --out-surrogate`` and ``replay --json`` of the demo bag (and gap's stderr)."""
    bag = root / "bags" / "demo_3d"
    folder = tmp_path_factory.mktemp("gap_demo")
    err = io.StringIO()
    argv = ["gap", str(bag), "--json", "--report", str(folder / "report")]
    with contextlib.redirect_stderr(err):
        gap = json.loads(_cli([*argv, "--out-surrogate", str(folder / "after.yaml")]))
    replay = json.loads(_cli(["replay", str(bag), "--json"]))
    return gap, replay, folder / "report", err.getvalue()


def test_gap_before_is_the_replay_posterior(demo):
    gap, replay, *_ = demo
    before = gap["posterior"]["before"]
    np.testing.assert_allclose(before["mean_m"], replay["posterior"]["mean_m"], rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(before["covariance_m2"], replay["posterior"]["covariance_m2"], rtol=1e-12)
    assert "replay" in before["what"]


def test_gap_after_adding_the_named_effects_is_the_papers_offset(demo):
    gap, *_ = demo
    after = gap["posterior"]["after"]
    assert set(after["effects_added"]) == {"vertical_gradient", "transverse_gradient", "traffic"}
    # the twin's offset (+0.7 / -0.7 mm), which the as-built shadow reads as +0.67 / -0.64
    np.testing.assert_allclose(after["mean_m"], [7e-4, -7e-4], atol=2e-5)


def test_the_events_of_each_run_are_said_where_the_change_moved_them(demo):
    """Before and after carry the events their runs found; the text names them when they differ.

    On the demo the run after the named effects finds a step (about -0.02 mm) that the run
    before does not: its posterior read "the state since the settlement step at ..." with no
    event anywhere in the output.
    """
    gap, replay, *_ = demo
    from bridge_shadow.commands.gap import _human

    before, after = gap["posterior"]["before"], gap["posterior"]["after"]
    assert [e["time_ns"] for e in before["events"]] == [e["time_ns"] for e in replay["events"]]
    if after["state"]["kind"] == "event":
        assert after["events"] and after["events"][-1]["time_ns"] == after["state"]["since_ns"]
    lines = [line.strip() for line in _human(gap).splitlines() if line.strip().startswith("events ")]
    if [e["time"] for e in before["events"]] != [e["time"] for e in after["events"]]:
        assert len(lines) == 2 and all(e["time"] in lines[1] for e in after["events"])
    else:
        assert lines == []


def test_text_and_report_say_what_each_number_is(demo):
    gap, _, report, _ = demo
    from bridge_shadow.commands.gap import _human

    text = _human(gap)
    before = next(line for line in text.splitlines() if line.strip().startswith("before"))
    after = next(line for line in text.splitlines() if line.strip().startswith("after"))
    assert "replay" in before and "model in use" in before
    assert "vertical_gradient" in after and "added to the model" in after
    mm = [round(1e3 * v, 3) for v in gap["posterior"]["after"]["mean_m"]]
    assert f"{mm[0]:+.3f} / {mm[1]:+.3f}" in after
    # an effect implausible alone in the rank table and named with the ones before it: the legend
    # says why both stand (it read as an implausible fit named as present)
    alone = next(c for c in gap["candidates"] if c["effect"] == "transverse_gradient")
    named = [gap["best_effect"]["effect"], *(a["effect"] for a in gap["also_present"])]
    assert not alone["plausible"] and "transverse_gradient" in named
    assert "fit: each effect alone" in text and "fitted with the ones named before it" in text
    md = (report / "report.md").read_text()
    assert "| before |" in md and "| after |" in md
    for png in ("residual.png", "breakdown.png", "heldout.png"):
        assert (report / png).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_the_surrogate_written_says_which_named_effects_it_cannot_carry(demo):
    """The demo's named effects are loads taken off the record: the file is the model in use, and says so.

    ``replay --surrogate`` with it gives ``before``, not ``after``; the file's header and a WARN line
    say which effects it leaves out (a stiffness named is carried: ``test_gap_realdata``).
    """
    from bridge_shadow.model.surrogate_file import load_surrogate

    gap, _, _, err = demo
    after = gap["posterior"]["after"]
    assert after["effects_in_surrogate"] == []
    assert set(after["effects_off_the_record"]) == {"vertical_gradient", "transverse_gradient", "traffic"}
    written = Path(gap["surrogate_written"])
    header = written.read_text().split("\nA:", 1)[0]
    assert "with what changes the model: none" in header and "Not in it:" in header
    np.testing.assert_allclose(load_surrogate(written).A, load_surrogate().A, rtol=1e-15)
    again = json.loads(_cli(["replay", gap["bag"], "--json", "--surrogate", str(written)]))
    np.testing.assert_allclose(again["posterior"]["mean_m"], gap["posterior"]["before"]["mean_m"], rtol=1e-12)
    warn = [line for line in err.splitlines() if "WARN" in line]
    assert len(warn) == 1 and "does not carry" in warn[0] and "traffic" in warn[0]
