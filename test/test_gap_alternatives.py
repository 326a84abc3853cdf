"""``gap --alternatives``: the shadow with each effect the data cannot tell from the named one.

Nothing tested the option: on the real pair, whose named effect stands alone, it added nothing
and said nothing. Here a twin's load-test day whose imposed steps cannot tell three stiffnesses
apart runs one replay per stand-in, and a case with none says so (an empty block, one line).
"""

from __future__ import annotations

import numpy as np

from bridge_shadow.commands.gap import _human


def test_each_indistinguishable_stiffness_is_run_standing_in_for_the_named_one() -> None:
    from bridge_shadow.gap.diagnose import diagnose
    from bridge_shadow.twin import scenarios

    data, model, path, imposed, _ = scenarios._load_test("nonlinear", 2, None)
    s = diagnose(data, model, imposed=imposed, shadow=True, surrogate_path=path, alternatives=True).summary
    group = s["levels"]["imposed"]["indistinguishable_from"]
    post = s["posterior"]
    assert group and set(post["alternatives"]) == set(group)
    for name, alt in post["alternatives"].items():
        assert alt["what"].startswith(f"if {name} ")
        assert np.all(np.isfinite(alt["mean_m"])) and np.all(np.asarray(alt["sigma_m"]) > 0)
        # a stand-in fits the same steps: its reading differs from the named one's by less than the
        # interval, and it is another model (not the named one run again)
        diff = np.abs(np.asarray(alt["mean_m"]) - np.asarray(post["after"]["mean_m"]))
        assert np.all(diff <= 1.96 * np.asarray(post["after"]["sigma_m"])) and np.any(diff > 1e-6)
    text = _human(s)
    assert sum(line.startswith("  or ") for line in text.splitlines()) == len(group)
    assert "none to run" not in text


def test_none_to_run_is_said() -> None:
    from bridge_shadow.gap.diagnose import diagnose
    from bridge_shadow.twin import scenarios

    data, model, path, imposed, _ = scenarios._load_test("stiffer", 300, None)
    s = diagnose(data, model, imposed=imposed, shadow=True, surrogate_path=path, alternatives=True).summary
    assert s["levels"]["imposed"]["indistinguishable_from"] == [] and s["posterior"]["alternatives"] == {}
    assert "--alternatives: none to run" in _human(s)
    plain = diagnose(data, model, imposed=imposed, shadow=True, surrogate_path=path).summary
    assert "alternatives" not in plain["posterior"] and "none to run" not in _human(plain)
