"""Many bridges live: one launch starts a shadow node per bridge, each in its own namespace.

``bridge_shadow_fleet FLEET.yaml`` (the project's launch file: ``launch`` is not on the package
index, ``ros.launcher.NodeProcess`` is the launcher) reads::

    bridges:
      munich:                        # the bridge's namespace: /munich
        params: munich/shadow.yaml   # optional: its parameter file (default config/shadow.yaml)
        surrogate: munich/surrogate.yaml   # optional: its surrogate (else the parameters')
      ...

(the archive manifest's format; ``bags`` entries are ignored here) and starts one
``bridge_shadow_node`` per bridge, in one DDS domain on loopback, with

- namespace ``/NAME`` (``-r __ns:=/NAME``): the node is ``/NAME/bridge_shadow``, its services
  ``/NAME/bridge_shadow/flush``, ``status`` and ``history``, its ``/diagnostics`` statuses are
  named ``NAME/bridge_shadow: ...``;
- the contract's topics under the namespace: ``/NAME/bridge/frc_01/force`` in,
  ``/NAME/bridge_shadow/settlement/mean`` out, and so on (the ``topic_*`` parameters made
  relative);
- its parameters, checked before anything starts (one line and exit 2 on a bad file), written
  with the surrogate's path into a parameter file of its own (``/**`` section: one node a process).

The fleet runs until SIGINT/SIGTERM and then stops every node (each writes its checkpoint when
its parameters name one: each bridge needs its own ``checkpoint_path``, two bridges naming one
file are refused). Every node's output (its start-up lines, warnings, the checkpoint it wrote)
is relayed on stderr after its bridge's name, ``[munich] ...``. The exit code is 1 when a node
died, or stopped with an exit code other than 0 (a checkpoint it could not write, for one); one
node dying stops the others.
"""

from __future__ import annotations

import os
import re
import signal
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from bridge_shadow.errors import BridgeShadowError, InputError
from bridge_shadow.fileio import load_yaml, yaml_problem
from bridge_shadow.ros.launcher import NodeProcess

__all__ = ["FleetMember", "member_args", "read_fleet", "start_fleet"]

_NAME = re.compile(r"^[A-Za-z][A-Za-z0-9_]*$")


@dataclass
class FleetMember:
    """One bridge of a fleet: its name (namespace), parameter file and surrogate file."""

    name: str
    params: Path | None = None
    surrogate: Path | None = None


def read_fleet(path: str | Path) -> list[FleetMember]:
    """Read a fleet file (the archive manifest's format; ``bags`` are ignored).

    Raises:
        InputError: the file is not a fleet, a name is not a ROS name, or a path is not a string.

    """
    import yaml

    file = Path(path)
    try:
        doc = load_yaml(file.read_text(encoding="utf-8"))
    except yaml.YAMLError as err:
        raise InputError(f"{file}: cannot read the fleet file ({yaml_problem(err)})") from None
    except (OSError, UnicodeDecodeError) as err:
        raise InputError(f"{file}: cannot read the fleet file ({' '.join(str(err).split())})") from None
    bridges = doc.get("bridges") if isinstance(doc, dict) else None
    if not isinstance(bridges, dict) or not bridges:
        raise InputError(f"{file}: a fleet file maps 'bridges' to {{name: {{params: ..., surrogate: ...}}}}")
    members = []
    for name, spec in bridges.items():
        if not _NAME.match(str(name)):
            raise InputError(
                f"{file}: bridge name {name!r} is not a ROS name (a letter, then letters, digits, _)"
            )
        spec = spec or {}
        if not isinstance(spec, dict) or set(spec) - {"params", "surrogate", "bags"}:
            raise InputError(f"{file}: bridge {name}: expected params, surrogate (and bags, ignored)")
        paths = []
        for key in ("params", "surrogate"):
            value = spec.get(key)
            if value is not None and not isinstance(value, str):
                raise InputError(f"{file}: bridge {name}: {key} must be a path")
            paths.append(
                None
                if value is None
                else (file.parent / value if not Path(value).is_absolute() else Path(value))
            )
        members.append(FleetMember(str(name), *paths))
    return members


def member_params(member: FleetMember) -> dict[str, Any]:
    """Return the member's node parameters: its file's, checked, with its surrogate and relative topics.

    Raises:
        ConfigError, InputError: a bad parameter or surrogate file (one line naming it).

    """
    from bridge_shadow.estimate.parameters.config import load_config
    from bridge_shadow.model.surrogate_file import load_surrogate

    over = {"surrogate_path": str(member.surrogate.resolve())} if member.surrogate else None
    config = load_config(member.params, over)  # validates the file against the parameter specs
    load_surrogate(config.surrogate_path or None)  # a bad surrogate stops the fleet before it starts
    params = config.to_params()  # every parameter, typed as checked (the node gets exactly these)
    for name, value in params.items():  # the topic names (not topic_timeout_s), relative to the namespace
        if name.startswith("topic_") and isinstance(value, str):
            params[name] = value.lstrip("/")
    return params


def member_args(member: FleetMember, params_file: Path) -> list[str]:
    """Return the node's command line: its namespace and its own parameter file."""
    return ["--ros-args", "-r", f"__ns:=/{member.name}", "--params-file", str(params_file)]


def start_fleet(members: list[FleetMember], folder: Path) -> list[NodeProcess]:
    """Write each member's parameter file into ``folder`` and start its node; return the processes."""
    import yaml

    plans = [(m, member_params(m)) for m in members]  # every file checked before any node starts
    writers: dict[Path, str] = {}
    for member, params in plans:  # two nodes writing one checkpoint would resume each other's state
        if not params.get("checkpoint_path"):
            continue
        path = Path(params["checkpoint_path"]).expanduser().resolve()
        if path in writers:
            raise InputError(
                f"bridges {writers[path]} and {member.name} both write the checkpoint {path}: "
                "give each bridge its own checkpoint_path"
            )
        writers[path] = member.name
    nodes = []
    for member, params in plans:
        file = folder / f"{member.name}.yaml"
        file.write_text(yaml.safe_dump({"/**": {"ros__parameters": params}}), encoding="utf-8")
        nodes.append(NodeProcess(member_args(member, file)).start())
    return nodes


def _relay(node: NodeProcess, member: FleetMember) -> None:
    """Print the node's new output lines on stderr, each after its bridge's name."""
    for line in node.new_lines():
        print(f"[{member.name}] {line}", file=sys.stderr)


def main(argv: list[str] | None = None) -> int:
    """Run a fleet until SIGINT/SIGTERM; exit 2 with one line on a bad fleet file.

    Each node's output is relayed on stderr after its bridge's name. Exit 1 when a node died, or
    stopped with an exit code other than 0 (its checkpoint not written, for one).
    """
    from bridge_shadow.ros.netenv import confine_to_loopback

    args = sys.argv[1:] if argv is None else argv
    if args and args[0] in ("-h", "--help"):  # the usage, the fleet file's format, what runs: stdout
        print(f"usage: bridge_shadow_fleet FLEET.yaml\n\n{__doc__}", end="")
        return 0
    if len(args) != 1:
        print(
            "usage: bridge_shadow_fleet FLEET.yaml\nbridge_shadow_fleet: error: expected one fleet file "
            "(--help shows its format)",
            file=sys.stderr,
        )
        return 2
    if "ROS_AUTOMATIC_DISCOVERY_RANGE" not in os.environ:
        confine_to_loopback()  # every node of the fleet in this one domain, on loopback
    stop: list[int] = []

    def on_signal(signum: int, frame: Any) -> None:
        stop.append(signum)

    previous = {sig: signal.signal(sig, on_signal) for sig in (signal.SIGINT, signal.SIGTERM)}
    nodes: list[NodeProcess] = []
    try:
        with tempfile.TemporaryDirectory(prefix="bridge_shadow_fleet_") as tmp:
            try:
                members = read_fleet(args[0])
                nodes = start_fleet(members, Path(tmp))
            except BridgeShadowError as err:
                print(f"bridge_shadow_fleet: error: {' '.join(str(err).split())}", file=sys.stderr)
                return 2
            names = ", ".join(f"/{m.name}" for m in members)
            print(f"bridge_shadow_fleet: {len(nodes)} nodes in namespaces {names}", file=sys.stderr)
            code = 0
            while not stop and not code:
                for node, member in zip(nodes, members, strict=True):
                    _relay(node, member)
                    try:
                        node.check_alive()
                    except BridgeShadowError as err:
                        print(f"bridge_shadow_fleet: {member.name}: {err}", file=sys.stderr)
                        code = 1  # one bridge down: the others are stopped (and checkpointed)
                        break
                else:
                    time.sleep(0.2)
            for node, member in zip(nodes, members, strict=True):
                running = node.proc is not None and node.proc.poll() is None
                end = node.stop()
                _relay(node, member)
                if running and end != 0:  # its last lines say why (a checkpoint not written, ...)
                    print(f"bridge_shadow_fleet: {member.name}: stopped with exit {end}", file=sys.stderr)
                    code = 1
            return code
    finally:
        for node in nodes:
            node.close()
        for sig, handler in previous.items():
            signal.signal(sig, handler)


if __name__ == "__main__":
    sys.exit(main())
