"""What every backend of a config of commands (``ir.Commands``) says alike.

The native module and the rclpy node must answer the same calls with the
same words, so the texts a caller reads are made here once, from the IR,
and each backend prints them into its module: the reasons of a failed
call, the usage of a command, the lines `help` answers on a served port.
The runtimes fill only the parts known at run time (the reply's text, what
did not fit).

Reasons (``{reply}`` and ``{why}`` are the runtime's):

- a YARP port that has no server: ``NO_YARP_SERVER``
- a YARP port or ROS 2 service that did not answer in time: ``TIMED_OUT``
- a ROS 2 service with no server: ``NO_ROS2_SERVER``
- a call that waited its whole timeout for the calls before it: ``WAITED``
- a reply that does not fit the response: ``UNFIT_REPLY``
- a command no section names: ``UNKNOWN_COMMAND``
- a command whose arguments do not fit: ``BAD_ARGUMENTS``

Exit totals, one line per service after the module's ``totals:`` line::

    service NAME: calls N, answered N, failed N (timed out N, no server N, did not fit N)

``stats`` on the module's RPC port, one list per service::

    (service NAME calls N answered N failed N timed_out N no_server N unfit N)
"""

from __future__ import annotations

from ybg.compiler import ir
from ybg.lower.rosnames import srv_type_name

NO_YARP_SERVER = "{target}: no server (is the module that serves it running?)"
NO_ROS2_SERVER = "{target}: no server"
TIMED_OUT = "{target} did not answer within {timeout} s"
WAITED = "{target}: the calls before this one took its {timeout} s"
UNFIT_REPLY = "{target} replied {reply}: {why}"
UNKNOWN_COMMAND = "unknown command {word}: `help` lists the commands"
BAD_ARGUMENTS = "`{usage}`: {why}"

#: the exit totals line of one service (Python format; the C++ runtime prints the same)
TOTALS_LINE = ("service {name}: calls {calls}, answered {answered}, failed {failed} "
               "(timed out {timed_out}, no server {no_server}, did not fit {unfit})")
#: the keys of one service's `stats` list, after ``service NAME``
STATS_KEYS = ("calls", "answered", "failed", "timed_out", "no_server", "unfit")


def describe(service: ir.Service) -> str:
    """The start-up line of a service: what it serves and what it calls (the
    native module's and the rclpy node's words)."""
    kind = srv_type_name(service.srv_type)
    timeout = timeout_text(service.timeout)
    if service.serves == "ros2":
        return (f"service {service.name}: serves the ROS 2 service {service.service} ({kind}) and calls the "
                f"YARP RPC port {service.port} (timeout {timeout} s)")
    return (f"service {service.name}: serves `{usage(service)}` on the YARP RPC port {service.port} and "
            f"calls the ROS 2 service {service.service} ({kind}) (timeout {timeout} s)")


def summary(commands: ir.Commands) -> str:
    """What a package of ``commands`` is, for its description."""
    return f"Commands between YARP RPC ports and ROS 2 services ({', '.join(s.service for s in commands.services)})"


def timeout_text(seconds: float) -> str:
    """A timeout as the reasons say it: ``5``, ``1.5``, ``0.25``."""
    return f"{seconds:g}"


def target(service: ir.Service) -> str:
    """What the module calls: the YARP port (serves ros2) or the ROS 2 service."""
    return service.port if service.serves == "ros2" else service.service


def reasons(service: ir.Service) -> dict[str, str]:
    """The reasons of a failed call of ``service`` with everything known
    before it runs filled in; ``{reply}`` and ``{why}`` stay for the runtime."""
    t = target(service)
    timeout = timeout_text(service.timeout)
    no_server = NO_YARP_SERVER if service.serves == "ros2" else NO_ROS2_SERVER
    return {
        "no_server": no_server.format(target=t),
        "timed_out": TIMED_OUT.format(target=t, timeout=timeout),
        "waited": WAITED.format(target=t, timeout=timeout),
        "unfit_reply": UNFIT_REPLY.replace("{target}", t),
        "bad_arguments": BAD_ARGUMENTS.replace("{usage}", usage(service)),
    }


def argument_names(service: ir.Service) -> list[str]:
    """For a served command, a name for each declared argument: the request
    field it fills (``x``, ``target.y``), else ``arg<i>``."""
    width = service.width or 0
    names = [f"arg{i}" for i in range(width)]
    for f in service.fills:
        if f.source != "element":
            continue
        if f.slice:
            stop = width if f.stop is None else f.stop
            for k in range(f.start, min(stop, width)):
                names[k] = f"{f.ref.dotted}[{k - f.start}]"
        elif f.start < width:
            names[f.start] = f.ref.dotted
    return names


def usage(service: ir.Service) -> str:
    """A served command as `help` shows it: ``track data:int32``,
    ``look x:float64 y:float64 z:float64``; a command with undeclared
    arguments: ``goto ...``."""
    if service.serves != "yarp":
        return service.name
    if service.layout is None:
        return f"{service.name} ..."
    types = [g.type for g in service.layout for _ in range(g.count)]
    parts = [service.name] + [f"{n}:{t}" for n, t in zip(argument_names(service), types)]
    return " ".join(parts)


def help_lines(commands: ir.Commands, port: str) -> list[str]:
    """What `help` answers on the served ``port``, a string each (after the
    vocab ``many``, as YARP modules answer): a line per command, then help's own."""
    lines = [f"{usage(s)}: calls the ROS 2 service {s.service} ({s.srv_type})"
             for s in commands.on_port(port)]
    lines.append("help: this list")
    return lines


def unknown_command(word: str) -> str:
    return UNKNOWN_COMMAND.format(word=word)
