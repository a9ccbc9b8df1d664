"""What ``ybgc init`` makes of a survey of a running robot (pure: no YARP
here; :mod:`ybg.init.survey` asks the robot): which ports become which
bridge, each bridge's config text, and the ports it reports instead of
guessing.

The kinds it knows, each from what a port's name and its Bottles say
(docs/init.md):

- **joints**: a controlboard's ``<part>/state:o`` (numbers), as a
  sensor_msgs/JointState on ``/joint_states``, radians from degrees, the
  joint names from the part's ``rpc:i`` (`get axes`, `get name j`), else
  numbered and marked for the user to name;
- **imu**: 12 numbers from a port named ``inertial`` or ``imu`` (iCub's
  inertial layout: roll pitch yaw in degrees, accelerometer, gyroscope in
  deg/s, magnetometer), as a sensor_msgs/Imu;
- **wrench**: 6 numbers from a port named ``analog``, ``ft``, ``wrench`` or
  ``force``, as a geometry_msgs/WrenchStamped (force then torque);
- **camera**: YARP images, as a sensor_msgs/Image of their pixel type;
- **command**: an RPC port that answers `help`, as a commented draft of a
  std_srvs/Trigger service (``.ini.draft``: no tool takes it for a config
  until the user has written what to send and renamed it).

Anything else is reported with why, and nothing is written for it."""

from __future__ import annotations

import re
from dataclasses import dataclass, field

from ybg.compiler.names import sanitize_identifier
from ybg.probe.layout import NUMBERS

#: YARP pixel codes (vocabs) -> the encodings a config names (docs/config.md, images)
ENCODINGS = {"rgb": "rgb8", "bgr": "bgr8", "rgba": "rgba8", "bgra": "bgra8", "mono": "mono8",
             "mo16": "mono16", "dec": "32FC1"}

#: rates a port's measured rate is rounded to, when within 10 %
_ROUND_RATES = (1, 2, 5, 10, 15, 20, 25, 30, 50, 60, 100, 120, 125, 200, 250, 500, 1000)


@dataclass
class Bridge:
    """A config ``ybgc init`` writes: ``file`` (in the output folder),
    ``kind``, the ``ports`` it reads, its ``text``; ``draft``: written as a
    commented draft, not a config."""

    file: str
    kind: str
    module: str
    ports: list
    text: str
    draft: bool = False


@dataclass
class Reported:
    """A port ``ybgc init`` writes nothing for, and why."""

    port: str
    why: str


@dataclass
class Plan:
    robot: str
    bridges: list = field(default_factory=list)
    reported: list = field(default_factory=list)


def robot_name(prefix: str) -> str:
    """``/icub`` -> ``icub``; the whole name server (``/``) -> ``robot``."""
    last = prefix.rstrip("/").rsplit("/", 1)[-1]
    return sanitize_identifier(last) if last else "robot"


def nice_rate(rate: float | None) -> str:
    """A measured rate as said in a comment: ``100 Hz`` when within 10 % of a
    round rate, else to a tenth."""
    if rate is None:
        return "a rate not measured (fewer than 3 messages)"
    for r in _ROUND_RATES:
        if abs(rate - r) <= 0.1 * r:
            return f"about {r} Hz"
    return f"about {rate:.1f} Hz"


def _part(port: str, prefix: str) -> str:
    """The path of ``port`` below the prefix, without its last word's
    ``:o``: ``/icub/left_arm/state:o`` -> ``left_arm/state``."""
    rest = port[len(prefix.rstrip("/")):].strip("/") if prefix.strip("/") else port.strip("/")
    return re.sub(r":o$", "", rest)


def _ident(text: str) -> str:
    return sanitize_identifier(re.sub(r"[^A-Za-z0-9_]+", "_", text).strip("_")) or "port"


def _layout(elements) -> str | None:
    """The config's declaration of a Bottle of numbers: ``float64 x16``
    (every number as float64, which takes integers too); None if any
    element is not a number."""
    if elements is None or not elements or any(kind not in NUMBERS for kind, _ in elements):
        return None
    return f"float64 x{len(elements)}"


def _quoted(names) -> str:
    """A list of names as the config writes strings, several a line."""
    items = ['"' + n.replace("\\", "\\\\").replace('"', '\\"') + '"' for n in names]
    lines, line = [], ""
    for item in items:
        if line and len(line) + len(item) + 2 > 88:
            lines.append(line + ",")
            line = "       " + item
        else:
            line = item if not line else line + ", " + item
    lines.append(line)
    return "\n".join(lines)


def _header(lines, how: list[str], confirm: list[str]) -> str:
    out = [f"# {line}" for line in lines]
    out.append("#")
    out.append("# Written by `ybgc init` from the running robot:")
    out += [f"# - {h}" for h in how]
    if confirm:
        out.append("# To confirm before use:")
        out += [f"# - {c}" for c in confirm]
    return "\n".join(out) + "\n"


def _joints(plan: Plan, port: str, s, answers, prefix: str, used: set) -> Bridge | Reported:
    layout = _layout(s.first)
    if layout is None:
        return Reported(port, "a controlboard's state port that sent other values than numbers")
    n = len(s.first)
    part = _part(port, prefix).rsplit("/", 1)[0] or "joints"
    rpc = port[: -len("state:o")] + "rpc:i"
    if rpc not in answers and port[: -len("state:o")] + "nws/rpc:i" in answers:
        rpc = port[: -len("state:o")] + "nws/rpc:i"  # YARP 4.0's controlboard server
    got = answers.get(rpc)
    how = [f"{port} sent Bottles of {n} numbers ({nice_rate(s.rate())}, {s.bottles} in the sampling time)",
           "YARP's controlboards give joint positions in degrees: deg_to_rad makes them radians"]
    confirm = []
    if got is not None and got.names is not None and len(got.names) == n:
        names = got.names
        asked = "`getAxesRPC` ({}) and `getAxisNameRPC j`" if got.asked == "getAxesRPC" else \
            "`get axes` ({}) and `get name j`"
        how.append(f"the joint names: {rpc} answered {asked.format(got.axes)} for each")
    else:
        names = [f"{_ident(part)}_joint_{k}" for k in range(n)]
        if got is None:
            why = f"{rpc} is not listed"
        elif got.axes is not None and got.axes != n:
            why = f"{rpc} says {got.axes} axes, the state port sends {n} values"
        else:
            why = f"{rpc} did not answer " + ("`getAxesRPC` and `getAxisNameRPC j` (asked through `yarp rpc`)"
                                              if got.asked == "getAxesRPC" else "`get axes` and `get name j`")
        confirm.append(f"the joint names: numbered here ({why}); name them as the robot's URDF does")
    module = _unique(f"{plan.robot}_{_ident(part)}", used)
    text = _header([f"The joints of {part} on /joint_states (robot_state_publisher merges the parts),",
                    "in radians, stamped with the port's envelope, one message a Bottle."], how, confirm)
    text += (f"\n[module]\nname = {module}\n\n[output]\ntopic = /joint_states\ntype = sensor_msgs/JointState\n"
             f"\n[mux joints]\nports = {port} ({layout})\nconvert = deg_to_rad\n"
             f"\n[message]\nheader.stamp = timestamp(joints)\nname = {_quoted(names)}\nposition = joints\n")
    return Bridge(f"{_ident(part)}.ini", "joints", module, [port], text)


def _names(plan: Plan, port: str, prefix: str, used: set) -> tuple[str, str, str, str]:
    """A sensor's part (its path below the prefix), module name, the path its
    topic goes under (the port's folder) and frame id."""
    part = _part(port, prefix)
    return (part, _unique(f"{plan.robot}_{_ident(part)}", used), port.rsplit("/", 1)[0],
            f"{_ident(part)}_frame")


def _imu(plan: Plan, port: str, s, prefix: str, used: set) -> Bridge:
    part, module, base, frame = _names(plan, port, prefix, used)
    how = [f"{port} sent Bottles of 12 numbers ({nice_rate(s.rate())}), and its name says inertial",
           "the layout read as iCub's inertial sensor's: roll pitch yaw (deg), accelerometer (m/s^2), "
           "gyroscope (deg/s), magnetometer"]
    confirm = ["that the port's layout is the one above (a multipleanalogsensorsserver's is not)",
               f"the frame id ({frame}): the sensor's link in the URDF"]
    text = _header([f"The inertial sensor {port} as a sensor_msgs/Imu."], how, confirm)
    text += (f"\n[module]\nname = {module}\n\n[output]\ntopic = {base}/imu\ntype = sensor_msgs/Imu\n"
             f"\n[mux inertial]\nports = {port} (float64 x12)\n"
             "convert = euler_to_quat(rpy, deg)[0:3], deg_to_rad[7:10]\n"
             f"\n[message]\nheader.stamp = timestamp(inertial)\nheader.frame_id = \"{frame}\"\n"
             "orientation = inertial[0:4]\nangular_velocity = inertial[7:10]\nlinear_acceleration = inertial[4:7]\n")
    return Bridge(f"{_ident(part)}.ini", "imu", module, [port], text)


def _wrench(plan: Plan, port: str, s, prefix: str, used: set) -> Bridge:
    part, module, base, frame = _names(plan, port, prefix, used)
    how = [f"{port} sent Bottles of 6 numbers ({nice_rate(s.rate())}), and its name says a force/torque sensor",
           "read as fx fy fz (N) then tx ty tz (N m), as YARP's analog sensors send them"]
    confirm = [f"the frame id ({frame}): the sensor's link in the URDF"]
    text = _header([f"The force/torque sensor {port} as a geometry_msgs/WrenchStamped."], how, confirm)
    text += (f"\n[module]\nname = {module}\n\n[output]\ntopic = {base}/wrench\ntype = geometry_msgs/WrenchStamped\n"
             f"\n[mux ft]\nports = {port} (float64 x6)\n"
             f"\n[message]\nheader.stamp = timestamp(ft)\nheader.frame_id = \"{frame}\"\n"
             "wrench.force = ft[0:3]\nwrench.torque = ft[3:6]\n")
    return Bridge(f"{_ident(part)}.ini", "wrench", module, [port], text)


def _camera(plan: Plan, port: str, s, prefix: str, used: set) -> Bridge | Reported:
    code, width, height = s.image
    encoding = ENCODINGS.get(code)
    if encoding is None:
        return Reported(port, f"YARP images of the pixel code `{code}`, which has no ROS encoding ybgc converts "
                              f"(it converts {', '.join(sorted(ENCODINGS))})")
    part, module, _, frame = _names(plan, port, prefix, used)
    how = [f"{port} sent {width}x{height} images of pixel code `{code}` ({nice_rate(s.rate())})",
           "its CameraInfo says the size and no calibration (k all zeros: ROS's uncalibrated camera)"]
    confirm = [f"the frame id ({frame}): the camera's optical frame in the URDF",
               "the calibration: the robot's camera calibration file in [camera_info] "
               "(calibration = \"<file>\", <group>; docs/config.md)"]
    text = _header([f"The camera {port} as a sensor_msgs/Image ({encoding}) and its CameraInfo."], how, confirm)
    text += (f"\n[module]\nname = {module}\n\n[mux image]\nports = {port} (image {encoding})\n"
             f"\n[output]\ntopic = {port}/image_raw\ntype = sensor_msgs/Image\n"
             f"\n[message]\nheader.frame_id = \"{frame}\"\ndata = image\n"
             f"\n[camera_info]\nwidth = {width}\nheight = {height}\n")
    return Bridge(f"{_ident(part)}.ini", "camera", module, [port], text)


def _command(plan: Plan, port: str, answers, prefix: str, used: set) -> Bridge:
    part = _part(port, prefix)
    stem = re.sub(r"_?rpc(_i)?$", "", _ident(part)) or _ident(part)
    module = _unique(f"{plan.robot}_{stem}_commands", used)
    said = " ".join(answers.help.split())
    said = said if len(said) <= 160 else said[:157] + "..."
    lines = [f"A DRAFT: the RPC port {port} as a std_srvs/Trigger service.",
             f"It answered `help` with: {said}",
             "Write the command to send (`send`), uncomment, and rename this file to .ini.",
             "Written by `ybgc init` from the running robot.",
             "",
             "[module]",
             f"name = {module}",
             "",
             f"[service {stem}]",
             f"serve = {port.rsplit('/', 1)[0] or '/' + stem} (std_srvs/Trigger)",
             f"call = {port} (string x1)",
             'send = "the", "command"',
             "timeout = 5.0",
             "response.success = reply[0]",
             "response.message = reply"]
    text = "\n".join(("# " + line).rstrip() for line in lines) + "\n"
    return Bridge(f"{stem}_commands.ini.draft", "command", module, [port], text, draft=True)


def _unique(name: str, used: set) -> str:
    name = sanitize_identifier(name)
    out, k = name, 2
    while out in used:
        out, k = f"{name}_{k}", k + 1
    used.add(out)
    return out


def make(survey) -> Plan:
    """The bridges and reports for ``survey`` (:class:`ybg.init.survey.Survey`)."""
    from ybg.init.survey import controlboard_rpc, is_input, is_rpc

    plan = Plan(robot_name(survey.prefix))
    used: set = set()
    seconds = f"{survey.seconds:g} s"
    for port in survey.ports:
        s = survey.sampled.get(port)
        if is_rpc(port):
            got = survey.answers.get(port)
            if controlboard_rpc(port, survey.ports):
                continue  # read for its joint names
            if got is None or got.help is None:
                plan.reported.append(Reported(port, "an RPC port that did not answer `help`"))
            else:
                plan.bridges.append(_command(plan, port, got, survey.prefix, used))
            continue
        if is_input(port) or s is None:
            plan.reported.append(Reported(port, "an input port (its name ends in :i): nothing to read from it"))
            continue
        if s.refused:
            plan.reported.append(Reported(port, "took no connection from ybgc init's port"))
            continue
        if s.bottles == 0:
            plan.reported.append(Reported(port, f"sent nothing in the {seconds} of sampling"))
            continue
        if len(s.layouts) > 1:
            plan.reported.append(Reported(port, "sent Bottles of changing layouts: " + "; ".join(sorted(s.layouts))))
            continue
        if s.image is not None:
            found = _camera(plan, port, s, survey.prefix, used)
        elif port.endswith("/state:o"):
            found = _joints(plan, port, s, survey.answers, survey.prefix, used)
        else:
            found = _by_layout(plan, port, s, survey.prefix, used)
        (plan.reported if isinstance(found, Reported) else plan.bridges).append(found)
    _unique_files(plan.bridges)
    return plan


def _by_layout(plan: Plan, port: str, s, prefix: str, used: set) -> Bridge | Reported:
    n = len(s.first or [])
    words = port.lower()
    numbers = _layout(s.first) is not None
    if numbers and n == 12 and ("inertial" in words or "imu" in words):
        return _imu(plan, port, s, prefix, used)
    if numbers and n == 6 and any(w in words for w in ("analog", "/ft", "wrench", "force")):
        return _wrench(plan, port, s, prefix, used)
    from ybg.probe.layout import seen
    return Reported(port, f"sent Bottles of {seen(s.first or [])}: no kind ybgc init knows from this port's "
                          "name and layout; write its config by hand (docs/config.md)")


def _unique_files(bridges) -> None:
    taken: set = set()
    for b in bridges:
        stem, dot, ext = b.file.partition(".")
        name, k = b.file, 2
        while name in taken:
            name, k = f"{stem}_{k}{dot}{ext}", k + 1
        b.file = name
        taken.add(name)
