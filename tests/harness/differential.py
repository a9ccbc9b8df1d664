"""The native ROS 2 module (cpp) and the rclpy node (ros2) of one program,
fed the same YARP streams, each with an rclpy subscriber: the messages of
both, compared bit for bit (``float_bits``).
"""
from __future__ import annotations

import dataclasses
import random
import signal
from pathlib import Path

from harness.env import VENV
from harness.launchers import write_node
from harness.module import EXIT_BOUND, Module
from harness.ros2 import subscriber_for
from harness.yarp import YarpProducer

def float_bits(value):
    """A message as JSON gives it, each float replaced by its exact bits."""
    if isinstance(value, float):
        return value.hex()
    if isinstance(value, list):
        return [float_bits(v) for v in value]
    if isinstance(value, dict):
        return {k: float_bits(v) for k, v in value.items()}
    return value


class Differential:
    """The native module of ``key`` and the rclpy node of the same program
    (--backend ros2, on a topic of its own), fed the same YARP streams, each
    with an rclpy subscriber."""

    def __init__(self, builds, key: str, env: dict, tmp_path: Path):
        self.program = program = builds.programs[key]
        node_program = dataclasses.replace(program, module=f"{program.module}_node",
                                           output=dataclasses.replace(program.output,
                                                                      name=program.output.name + "_node"))
        self.native = Module([builds.exe(key)], env=env, name=key)
        self.node = Module([VENV / "bin" / "python", write_node(node_program, tmp_path)], env=env,
                           name=node_program.module)
        self.subs = [subscriber_for(env, p) for p in (program, node_program)]
        self.node_topic = node_program.output.name
        self.producers = {i.name: YarpProducer(env, i.name) for m in program.muxes for i in m.inputs}
        self.procs = [self.native, self.node, *self.subs, *self.producers.values()]

    def __enter__(self) -> "Differential":
        try:
            for p in self.procs:
                p.start()
            self.native.wait_log("event-driven")
            self.node.wait_log("event-driven")
            for producer in self.producers.values():
                producer.wait_outputs(2)
            for s in self.subs:
                s.wait_publishers(1)
            # and each publisher has matched its subscriber: a message
            # published before that is lost (discovery is not symmetric in time)
            self.native.wait_log(f"{self.program.output.name}: 1 subscriber\n")
            self.node.wait_log(f"{self.node_topic}: 1 subscriber\n")
        except BaseException:
            self.__exit__()
            raise
        return self

    def __exit__(self, *exc) -> None:
        for p in reversed(self.procs):
            p.stop()

    def round(self, k: int, bottles: dict, rng: random.Random) -> None:
        """Writes one Bottle to each port (in the config's order, each with an
        envelope), then waits for message k + 1 of both."""
        for port, values in bottles.items():
            self.producers[port].write(values, stamp=[k, 1.7e9 + rng.uniform(0, 1e6)])
        for s in self.subs:
            s.wait_for(k + 1)

    def messages(self, rounds: int) -> list:
        """The messages of both, the same bit for bit (the native module's);
        SIGINT ends the native module with 0 within 2 s, its totals said."""
        native_msgs, node_msgs = ([float_bits(m.msg) for m in s.messages] for s in self.subs)
        assert len(native_msgs) == len(node_msgs) == rounds
        assert native_msgs == node_msgs
        rc, elapsed = self.native.interrupt(signal.SIGINT)
        assert rc == 0 and elapsed < EXIT_BOUND, self.native.log_text()[-2000:]
        log = self.native.log_text()
        assert f"published {rounds} messages" in log and "Traceback" not in log, log[-2000:]
        return native_msgs
