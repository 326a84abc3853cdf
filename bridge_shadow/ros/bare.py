"""A bare subscriber of the three input topics: the baseline of the live throughput benchmark.

It does what any rclpy node must do to receive the inputs and nothing else: an
``EventsExecutor``, one subscription per topic (raw CDR bytes by default, typed messages with
``--typed``) whose callback appends the message to a list, and the node's status, flush and history services
(``std_srvs/Trigger``) so the same ``Player`` drives it. With ``--echo`` it also publishes every
frc_02 message back on ``ECHO_TOPIC`` (the transport round trip of the latency benchmark). Run:
``python -m bridge_shadow.ros.bare [--typed] [--echo]``.
"""

from __future__ import annotations

import json
import signal
import sys

import rclpy
from geometry_msgs.msg import WrenchStamped
from rclpy.experimental import EventsExecutor
from rclpy.node import Node
from rclpy.signals import SignalHandlerOptions
from rclpy.task import Future
from sensor_msgs.msg import Temperature
from std_srvs.srv import Trigger

from bridge_shadow.contract import NODE_NAME
from bridge_shadow.ros.live_replay import INPUT_ORDER
from bridge_shadow.ros.netenv import confine_to_loopback
from bridge_shadow.ros.node import FLUSH_SERVICE, HISTORY_SERVICE, STATUS_SERVICE, input_qos

__all__ = ["ECHO_TOPIC", "BareSubscriber", "main"]

#: With ``--echo`` every frc_02 message is published back here as it came (latency baseline). The
#: bare node's names are relative: the contract's in the root namespace, under ``/NS`` when it is
#: started in one (``-r __ns:=/NS``: the baseline of a fleet, ``benchmarks/fleet_live.py``).
ECHO_TOPIC = "bridge_shadow_bench/echo"


class BareSubscriber(Node):
    """Count the input messages; answer status and flush with the counts."""

    def __init__(self, typed: bool = False, depth: int = 1000, echo: bool = False) -> None:
        super().__init__(NODE_NAME)
        self.buffers: list[list[object]] = [[], [], []]
        types = (WrenchStamped, WrenchStamped, Temperature)
        self._subs = [
            self.create_subscription(t, topic, buf.append, input_qos(depth), raw=not typed)
            for t, topic, buf in zip(types, [t.lstrip("/") for t in INPUT_ORDER], self.buffers, strict=True)
        ]
        names = (STATUS_SERVICE, FLUSH_SERVICE, HISTORY_SERVICE)
        self._srv = [self.create_service(Trigger, name, self._answer) for name in names]
        if echo:
            pub = self.create_publisher(WrenchStamped, ECHO_TOPIC, input_qos(depth))
            self._subs.append(
                self.create_subscription(
                    WrenchStamped, INPUT_ORDER[1].lstrip("/"), pub.publish, input_qos(0), raw=True
                )
            )

    def _answer(self, request: object, response: Trigger.Response) -> Trigger.Response:
        taken = [len(b) for b in self.buffers]
        response.success = True
        response.message = json.dumps({"taken": taken, "node": {"received": taken}})
        return response


def main(args: list[str] | None = None) -> int:
    """Spin until SIGINT/SIGTERM."""
    argv = sys.argv[1:] if args is None else list(args)
    confine_to_loopback()
    stop: list[int] = []
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda signum, frame: stop.append(signum))
    rclpy.init(args=[sys.argv[0], *argv], signal_handler_options=SignalHandlerOptions.NO)
    try:
        node = BareSubscriber(typed="--typed" in argv, echo="--echo" in argv)
        executor = EventsExecutor()
        executor.add_node(node)
        never = Future()  # the node's own loop (see bridge_shadow.ros.main)
        while not stop and rclpy.ok():
            executor.spin_until_future_complete(never, timeout_sec=0.2)
        node.destroy_node()
    finally:
        rclpy.try_shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main())
