"""Start a ROS node as a subprocess on loopback DDS, wait for it with a timeout, stop it by signal.

``launch`` is not on PyPI; this is the small piece the live replay, the tests and the benchmarks
need. The child runs ``python -m <module>`` with the venv's interpreter and an environment confined
to loopback in the caller's domain, so both ends of the graph meet and nothing leaves the host.
SIGINT, the stop signal, reaches the child's default handler even where the caller was started
with SIGINT ignored (a shell's background job, some service managers): an ignored signal is
inherited across ``exec``, and a child that cannot hear SIGINT is SIGKILLed after the grace (the
node hears it anyway, rclpy installing its own handler; a plain Python child does not).
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from types import TracebackType

from bridge_shadow.errors import BridgeShadowError
from bridge_shadow.ros.netenv import confine_to_loopback

__all__ = ["NodeError", "NodeProcess", "wait_until"]

#: ``python -m MODULE ARGS`` with SIGINT's default handler restored first (``runpy`` is what ``-m``
#: runs; ``sys.argv`` becomes the module's path and ARGS, as under ``-m``).
_RUN_MODULE = (
    "import runpy, signal, sys; signal.signal(signal.SIGINT, signal.default_int_handler); "
    "module = sys.argv.pop(1); runpy.run_module(module, run_name='__main__', alter_sys=True)"
)


class NodeError(BridgeShadowError):
    """A node subprocess failed to start, died, or did not answer in time."""


def wait_until(
    condition: Callable[[], bool],
    timeout_s: float,
    what: str,
    alive: Callable[[], None] | None = None,
    period_s: float = 0.01,
    wake: threading.Event | None = None,
) -> float:
    """Poll ``condition`` until true; return the seconds waited.

    ``alive`` is called on every poll and may raise (a dead peer); NodeError on timeout. ``wake``:
    an event whose setting (from another thread) makes the next poll at once rather than after
    ``period_s``.
    """
    t0 = time.monotonic()
    while not condition():
        if alive is not None:
            alive()
        if time.monotonic() - t0 > timeout_s:
            raise NodeError(f"timed out after {timeout_s:g} s waiting for {what}")
        if wake is None:
            time.sleep(period_s)
        else:
            wake.wait(period_s)
    return time.monotonic() - t0


class NodeProcess:
    """A node in a child process: ``with NodeProcess([...]) as node: ...`` stops it on exit.

    Attributes:
        args: arguments after ``python -m module`` (e.g. ``--ros-args -p name:=value``).
        env: the child's environment (loopback discovery, ``ROS_DOMAIN_ID`` of the caller).
        proc: the ``subprocess.Popen`` once started.
        killed_after_s: the grace ``stop`` gave before it had to SIGKILL the child (None: it exited).

    """

    def __init__(
        self,
        args: Sequence[str] = (),
        *,
        module: str = "bridge_shadow.ros.main",
        env: dict[str, str] | None = None,
    ) -> None:
        self.args = list(args)
        self.module = module
        self.env = dict(os.environ if env is None else env)
        if "ROS_AUTOMATIC_DISCOVERY_RANGE" not in self.env:
            confine_to_loopback(self.env)
        self.env.setdefault("AMENT_PREFIX_PATH", sys.prefix)
        self.env.setdefault("PYTHONUNBUFFERED", "1")
        self.proc: subprocess.Popen[bytes] | None = None
        self.killed_after_s: float | None = None
        self._log = tempfile.NamedTemporaryFile(prefix="bridge_shadow_node_", suffix=".log", delete=False)
        self._relayed = 0  # bytes of the log ``new_lines`` has returned

    @property
    def log_path(self) -> Path:
        """File holding the child's stdout and stderr."""
        return Path(self._log.name)

    def start(self) -> NodeProcess:
        """Start the child (non-blocking); use ``wait_until`` on the graph for readiness."""
        self.proc = subprocess.Popen(
            [sys.executable, "-c", _RUN_MODULE, self.module, *self.args],
            env=self.env,
            stdin=subprocess.DEVNULL,
            stdout=self._log,
            stderr=subprocess.STDOUT,
        )
        return self

    def output(self) -> str:
        """Return the child's output so far."""
        self._log.flush()
        return self.log_path.read_text(errors="replace")

    def new_lines(self) -> list[str]:
        """Return the child's complete output lines not returned before (for a caller that relays them)."""
        self._log.flush()
        with open(self.log_path, "rb") as fh:
            fh.seek(self._relayed)
            chunk = fh.read()
        end = chunk.rfind(b"\n") + 1
        self._relayed += end
        return chunk[:end].decode(errors="replace").splitlines()

    def check_alive(self) -> None:
        """Raise NodeError with the child's last output line if it has exited."""
        if self.proc is None:
            raise NodeError(f"{self.module}: not started")
        code = self.proc.poll()
        if code is not None:
            lines = [ln for ln in self.output().splitlines() if ln.strip()]
            last = lines[-1] if lines else "no output"
            raise NodeError(f"{self.module} exited with code {code}: {last}")

    def stop(self, sig: int = signal.SIGINT, timeout_s: float = 10.0) -> int:
        """Send ``sig``, wait up to ``timeout_s``, then SIGKILL; return the exit code."""
        if self.proc is None:
            return 0
        if self.proc.poll() is None:
            self.proc.send_signal(sig)
            try:
                self.proc.wait(timeout_s)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()
                self.killed_after_s = timeout_s
        return int(self.proc.returncode)

    def close(self) -> None:
        """Stop the child if needed and remove the log file."""
        self.stop()
        self._log.close()
        self.log_path.unlink(missing_ok=True)

    def __enter__(self) -> NodeProcess:
        return self.start()

    def __exit__(
        self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        self.close()
