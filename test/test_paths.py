"""Where the package looks for the real records: beside the checkout, or beside what it was cloned from."""

from __future__ import annotations

from pathlib import Path

from bridge_shadow.paths import _local_origin


def _git_config(root: Path, url: str) -> None:
    (root / ".git").mkdir(parents=True)
    (root / ".git" / "config").write_text(
        '[core]\n\tbare = false\n[remote "upstream"]\n\turl = /elsewhere\n'
        f'[remote "origin"]\n\turl = {url}\n\tfetch = +refs/heads/*:refs/remotes/origin/*\n'
    )


def test_a_local_clone_points_back_at_its_origin(tmp_path: Path) -> None:
    origin = tmp_path / "work" / "main"
    origin.mkdir(parents=True)
    clone = tmp_path / "elsewhere" / "p"
    _git_config(clone, str(origin))
    assert _local_origin(clone) == origin.resolve()
    other = tmp_path / "other" / "p"
    _git_config(other, f"file://{origin}")
    assert _local_origin(other) == origin.resolve()


def test_a_remote_or_missing_origin_gives_none(tmp_path: Path) -> None:
    remote = tmp_path / "a"
    _git_config(remote, "git@example:group/bridge_shadow.git")
    assert _local_origin(remote) is None
    assert _local_origin(tmp_path / "not_a_checkout") is None
