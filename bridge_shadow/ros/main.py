"""``bridge_shadow_node``: the command line of the live shadow (``ShadowNode`` in ``ros.node``).

``main`` checks the ``--params-file`` arguments, starts rclpy and spins the node until
SIGINT/SIGTERM, then writes the checkpoint; a configuration error is one line and exit code 2.

Network: before ``rclpy.init`` the node confines DDS discovery to loopback
(``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST`` and a ``ROS_DOMAIN_ID`` if none is set) unless the
environment already sets ``ROS_AUTOMATIC_DISCOVERY_RANGE``: an explicit choice (e.g. ``SUBNET`` on
a real monitoring network) is respected.

Executor: ``rclpy.experimental.EventsExecutor``, driven by ``spin_until_future_complete`` with a
0.2 s timeout in a loop that checks the stop flag; SIGINT/SIGTERM also complete the future it
waits on, which ends the spin even when a callback is always due. In rclpy 7.1 its ``spin()`` (and
``spin_until_future_complete`` without a timeout) neither returns on SIGINT/SIGTERM nor idles (it
busy-waits a core), so it is not used; ``spin_once`` per message costs a Python call per event.
"""

from __future__ import annotations

import os
import signal
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from bridge_shadow.contract import NODE_NAME
from bridge_shadow.errors import BridgeShadowError
from bridge_shadow.ros.netenv import check_domain_id, confine_to_loopback

__all__ = ["main", "params_files", "user_args"]

_STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM)

_USAGE = """\
usage: bridge_shadow_node [--ros-args [-p NAME:=VALUE ...] [--params-file FILE]]

The live digital shadow of the UniBw Munich test bridge: subscribes to the two central-bearing
load cells and the air temperature, publishes the posterior settlements, their covariance, the
temperature-compensated forces and /diagnostics. Parameters: config/shadow.yaml (documented there;
unknown names and bad values stop the node with one line). Stop with Ctrl-C or SIGTERM (a
checkpoint is written when checkpoint_path is set).
"""


def _in_ros_args(argv: Sequence[str]) -> list[bool | None]:
    """Per argument: inside a ``--ros-args`` section (True), outside (False), or a marker (None).

    A section runs from ``--ros-args`` to a ``--`` that ends it, or to the end of the line.
    """
    out: list[bool | None] = []
    in_ros = False
    for arg in argv:
        if arg == "--ros-args" or (arg == "--" and in_ros):
            in_ros = arg == "--ros-args"
            out.append(None)
        else:
            out.append(in_ros)
    return out


def params_files(argv: Sequence[str]) -> list[str]:
    """Return the ``--params-file FILE`` arguments of a ROS command line (after ``--ros-args``)."""
    inside = _in_ros_args(argv)
    return [
        argv[k + 1]
        for k, arg in enumerate(argv)
        if inside[k] and arg == "--params-file" and k + 1 < len(argv)
    ]


def user_args(argv: Sequence[str]) -> list[str]:
    """Return the arguments of a ROS command line outside ``--ros-args`` (before it, or after ``--``)."""
    return [arg for arg, inside in zip(argv, _in_ros_args(argv), strict=True) if inside is False]


def node_sections(argv: Sequence[str]) -> list[str]:
    """Return the parameter file sections that address this node (its remapped name and namespace)."""
    name, ns = NODE_NAME, ""
    inside = _in_ros_args(argv)
    for k, arg in enumerate(argv[:-1]):
        if inside[k] and arg in ("-r", "--remap"):
            rule = argv[k + 1]
            if rule.startswith("__node:=") or rule.startswith("__name:="):
                name = rule.split(":=", 1)[1]
            elif rule.startswith("__ns:="):
                ns = "/" + rule.split(":=", 1)[1].strip("/")
    full = f"{ns}/{name}" if ns not in ("", "/") else f"/{name}"
    return ["/**", f"/**/{name}", name, full, full.lstrip("/")]


def _check_params_file(path: str, sections: Sequence[str] = ()) -> str | None:
    """Read a ``--params-file`` before rcl does, so a broken one gives one line (not an RCLError).

    Return a warning when no section of the file addresses this node (``sections``): legal in ROS,
    but a copied file under another node's name sets nothing here, checkpoint_path included.
    """
    from bridge_shadow.estimate.parameters.config import read_params_file
    from bridge_shadow.fileio import load_yaml

    try:
        read_params_file(Path(path))
    except BridgeShadowError as err:
        if not ("expected" in str(err) and "ros__parameters" in str(err)):
            raise
    doc = load_yaml(Path(path).read_text(encoding="utf-8"))  # read above: valid YAML
    if not sections or not isinstance(doc, dict) or any(s in doc for s in sections):
        return None
    found = ", ".join(str(k) for k in doc) or "none"
    return (
        f"{path}: no section for this node ({sections[3]}, or /**): it sets nothing here "
        f"(its sections: {found})"
    )


class _stderr_held:
    """Hold what C code writes to file descriptor 2 in a block; pass it on unless ``drop()``ped."""

    def __enter__(self) -> _stderr_held:
        import tempfile

        sys.stderr.flush()
        self._file = tempfile.TemporaryFile()
        self._saved = os.dup(2)
        os.dup2(self._file.fileno(), 2)
        self._keep = True
        return self

    def drop(self) -> None:
        self._keep = False

    def __exit__(self, *exc: object) -> None:
        sys.stderr.flush()
        os.dup2(self._saved, 2)
        os.close(self._saved)
        if self._keep:
            self._file.seek(0)
            text = self._file.read()
            if text:
                sys.stderr.buffer.write(text)
                sys.stderr.flush()
        self._file.close()


def _one_line(err: BaseException) -> str:
    text = " ".join(str(err).split())
    return text[:400]


def main(args: list[str] | None = None) -> int:
    """Run the node until SIGINT/SIGTERM; return 0, or 2 with one line on a configuration error.

    Ctrl-C while it starts (its imports take seconds on a busy machine) is exit 130 without a
    traceback: rclpy and the shadow are imported here, not when the command loads this module.
    """
    try:
        return _main(args)
    except KeyboardInterrupt:
        return 130


def _main(args: list[str] | None) -> int:
    argv = sys.argv[1:] if args is None else list(args)
    if "--ros-args" not in argv and any(a in ("-h", "--help") for a in argv):
        print(_USAGE, end="")
        return 0
    prog = "bridge_shadow_node"
    extra = user_args(argv)
    if extra:  # the node takes no arguments of its own: a parameter outside --ros-args is ignored by ROS
        print(
            f"{prog}: error: unrecognized arguments: {' '.join(extra)} (parameters go after --ros-args: "
            f"{prog} --ros-args --params-file FILE -p NAME:=VALUE)",
            file=sys.stderr,
        )
        return 2
    files = params_files(argv)
    try:  # the warnings once rcl has read the files too (an error of its own is the one line)
        check_domain_id()
        unaddressed = [w for file in files if (w := _check_params_file(file, node_sections(argv)))]
    except BridgeShadowError as err:
        print(f"{prog}: {err}", file=sys.stderr)
        return 2
    import rclpy
    from rclpy.exceptions import ParameterException
    from rclpy.executors import ExternalShutdownException
    from rclpy.experimental import EventsExecutor
    from rclpy.signals import SignalHandlerOptions
    from rclpy.task import Future

    from bridge_shadow.ros.node import ShadowNode

    if "ROS_AUTOMATIC_DISCOVERY_RANGE" not in os.environ:
        confine_to_loopback()
    # SIGINT/SIGTERM set a flag and complete the future the executor waits on: the loop ends
    # between callbacks, so no callback is cut off by a context shut down under it, the exit path
    # still has a valid context, and a busy executor (a timer that is always due) still returns.
    stop: list[int] = []
    never = Future()

    def on_signal(signum: int, frame: Any) -> None:
        stop.append(signum)
        if not never.done():
            never.set_result(None)

    previous = {sig: signal.signal(sig, on_signal) for sig in _STOP_SIGNALS}
    node = None
    code = 0
    try:
        init_error = None
        with _stderr_held() as held:
            try:
                rclpy.init(args=[sys.argv[0], *argv], signal_handler_options=SignalHandlerOptions.NO)
            except Exception as err:  # RCLError: a -p rule or a file rcl cannot parse
                held.drop()  # rcl's own "[ERROR] ... Failed to parse" line: ours says it once
                init_error = err
        if init_error is not None:
            print(f"{prog}: cannot read the ROS arguments: {_one_line(init_error)}", file=sys.stderr)
            return 2
        for warning in unaddressed:
            print(f"{prog}: WARN: {warning}", file=sys.stderr)
        node = ShadowNode(params_files=files)
        executor = EventsExecutor()
        executor.add_node(node)
        while not stop and rclpy.ok():
            executor.spin_until_future_complete(never, timeout_sec=0.2)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except BridgeShadowError as err:
        print(f"{prog}: {err}", file=sys.stderr)
        code = 2
    except ParameterException as err:  # refused by rclpy itself
        print(f"{prog}: {_one_line(err)}", file=sys.stderr)
        code = 2
    finally:
        if node is not None:
            try:
                path = node.save_on_exit()
                if path is not None:
                    print(f"{prog}: checkpoint written to {path}", file=sys.stderr)
            except BridgeShadowError as err:  # a failure at run time (the path was checked at start)
                print(f"{prog}: checkpoint not written: {err}", file=sys.stderr)
                code = code or 1
            node.destroy_node()
        rclpy.try_shutdown()
        for sig, handler in previous.items():
            signal.signal(sig, handler)
    return code


if __name__ == "__main__":
    sys.exit(main())
