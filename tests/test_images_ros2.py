"""Camera images through the ``ros2`` backend's node, both ways, on real
YARP and real ROS 2: nodes generated with ``ybgc CONFIG --backend ros2``
and the image peer (tests/peers/image_peer.py), every pixel checked by its
hash (tests/peers/image_data.py).

YARP -> ROS 2: one node per declared encoding, all reading the one producer
port and publishing on the one topic, so that every frame is published by
the nodes of its pixel type and refused by all the others (their exit
totals count it; nothing is published from it); the rgb8 node publishes
its CameraInfo (a calibration file in iCub's format, at 320x240) beside
each image. Odd sizes (321x241) with YARP's row padding, resolution
changes, stamps from the envelope.

ROS 2 -> YARP: one node, a ROS 2 publisher with padded rows, a YARP reader:
every encoding with a YARP pixel type, rows packed (quantum 1), the stamp
as the envelope, an encoding without a pixel type refused.

The processes of each direction are started once (a module's fixture) and
shared by its cases; the last case of each direction stops its nodes and
checks their exit totals against everything its cases sent.
"""
from __future__ import annotations

import math
import re
import time
from dataclasses import dataclass, field
from pathlib import Path

import pytest

from harness.module import Node, stop_clean
from harness.images import ImagePeer, image_data
from harness.ros2 import Ros2Domain, ros2_environment
from harness.yarp import YarpServer
from ybg import cli

# on YARP 3.5 and 4.0.0: 3.12.3 is the version tests' (docs/yarp-versions.md)
pytestmark = pytest.mark.yarp_ends


W, H = 321, 241  # odd: every row of every pixel type padded by YARP's default quantum (8)

#: the declared encodings of the YARP -> ROS 2 nodes (mono16 and 16UC1 are one YARP pixel type)
ENCODINGS = ("rgb8", "bgr8", "rgba8", "mono8", "mono16", "16UC1", "32FC1")
YARP_SOURCE = "/ybg_cam/image:o"
IMAGE_TOPIC = "/ybg_cam/image_raw"
INFO_TOPIC = "/ybg_cam/camera_info"

#: the camera calibration of the rgb8 node (iCub's format), done at 320x240
CALIBRATION = {"w": 320, "h": 240, "fx": 219.057, "fy": 219.028, "cx": 174.742, "cy": 102.874,
               "k1": -0.374173, "k2": 0.205428, "p1": 0.00282356, "p2": 0.00270998}

ROS_TOPIC = "/ybg_camera/image_raw"
YARP_OUTPUT = "/ybg_camera/image:o"
YARP_READER = "/ybg_camera/reader"


def ns_of(seconds: float) -> list:
    """A time in seconds as the node stamps it: (sec, nanosec), exact."""
    sec = math.floor(seconds)
    return [sec, round((seconds - sec) * 1e9)]


def generate(config: Path, out: Path) -> Path:
    """``ybgc CONFIG --backend ros2 -o OUT``; the node's path."""
    assert cli.main([str(config), "--backend", "ros2", "-o", str(out)]) == 0
    module = re.search(r"^name = (\S+)$", config.read_text(), re.M).group(1)
    return out / f"{module}_node.py"


#: the nodes of this file's tests, shared by several of them
_NODES: list = []


def start_node(env: dict, path: Path, *args: str) -> Node:
    node = Node(env, path, *args).start()
    _NODES.append(node)
    return node


@pytest.fixture(autouse=True)
def _print_node_logs():
    """The logs of the nodes so far, shown by pytest when a test fails."""
    yield
    for node in _NODES:
        print(f"---- log of {node.name}:\n{node.log_text()[-3000:]}")


def input_totals(log: str, source: str) -> dict:
    """The exit totals of one input, and the published count."""
    m = re.search(r"input %s: received (\d+), dropped (\d+), stale periods (\d+), unused (\d+)"
                  r"(?:, refused (\d+) frames? \(([^)]*)\))?" % re.escape(source), log)
    assert m, log[-3000:]
    received, dropped, _stale, unused, refused, why = m.groups()
    published = int(re.search(r"published (\d+) messages", log).group(1))
    return {"received": int(received), "dropped": int(dropped), "unused": int(unused),
            "refused": int(refused or 0), "why": why, "published": published}


# --------------------------------------------------------------------------
# YARP -> ROS 2


def yarp_to_ros2_config(encoding: str, folder: Path) -> Path:
    module = "ybg_cam_" + encoding.lower()
    text = (f"[module]\nname = {module}\n\n[mux cam]\nports = {YARP_SOURCE} (image {encoding})\n\n"
            f"[output]\nvia = ros2\ntopic = {IMAGE_TOPIC}\ntype = sensor_msgs/Image\nreliability = reliable\n"
            f"depth = 10\n\n[message]\nheader.frame_id = \"cam_{encoding}\"\ndata = cam\n")
    if encoding == "rgb8":
        (folder / "eyes.ini").write_text("[CAMERA_CALIBRATION_LEFT]\nprojection pinhole\ndrawCenterCross 0\n"
                                         + "".join(f"{k} {v}\n" for k, v in CALIBRATION.items()))
        text += "\n[camera_info]\ncalibration = \"eyes.ini\", CAMERA_CALIBRATION_LEFT\n"
    path = folder / f"{module}.ini"
    path.write_text(text)
    return path


@dataclass
class YarpToRos2:
    """The nodes (by declared encoding), the producer, the subscriber, and
    what the cases sent: YARP pixel code -> frames."""
    nodes: dict
    producer: ImagePeer
    subscriber: ImagePeer
    sent: dict = field(default_factory=dict)
    seed: int = 1000


@pytest.fixture(scope="module")
def yarp_to_ros2(yarp, tmp_path_factory):
    folder = tmp_path_factory.mktemp("yarp_to_ros2")
    paths = {e: generate(yarp_to_ros2_config(e, folder), folder) for e in ENCODINGS}
    started = []
    with YarpServer(install=yarp) as server, Ros2Domain() as domain:
        env = ros2_environment(server.env, domain)
        try:
            producer = ImagePeer(env, {"mode": "yarp_pub", "port": YARP_SOURCE}, name="image_producer").start()
            started.append(producer)
            subscriber = ImagePeer(env, {"mode": "ros2_sub", "topic": IMAGE_TOPIC, "info_topic": INFO_TOPIC},
                                   name="image_subscriber").start()
            started.append(subscriber)
            nodes = {}
            for e, path in paths.items():  # started together: their start-up overlaps
                nodes[e] = start_node(env, path, "--ros-args", "-p", "timeout:=120.0")
                started.append(nodes[e])
            for e, node in nodes.items():
                node.wait_log(f"connected {YARP_SOURCE} -> ")
                node.wait_log(f"{IMAGE_TOPIC}: 1 subscriber\n")
            nodes["rgb8"].wait_log(f"{INFO_TOPIC}: 1 subscriber\n")
            subscriber.wait_event("matched", lambda ev: ev["n"] >= len(nodes))
            yield YarpToRos2(nodes, producer, subscriber)
        finally:
            for proc in reversed(started):
                proc.stop()


def takers(pixel: str) -> list:
    """The declared encodings whose nodes publish a frame sent as ``pixel``."""
    code = image_data.YARP_PIXELS[pixel]
    return [e for e in ENCODINGS if image_data.YARP_PIXELS[e] == code]


def send_yarp(rig: YarpToRos2, width: int, height: int, pixel: str, quantum: int = 8) -> dict:
    """One frame written by the YARP producer, with an envelope; each node of
    its pixel type publishes it: {encoding: the image received}; the
    CameraInfo of the rgb8 node too ("info")."""
    rig.seed += 1
    seed = rig.seed
    # 15 significant digits: YARP sends an envelope as text that keeps that many
    stamp = float("%d.%05d" % (1_700_000_000 + seed, 12345 + seed))
    rig.producer.send(cmd="frame", width=width, height=height, pixel=pixel, seed=seed, quantum=quantum,
                      stamp=[seed, stamp])
    rig.sent.setdefault(image_data.YARP_PIXELS[pixel], []).append(pixel)
    size = image_data.PIXEL_SIZES[pixel]
    digest = image_data.sha(width, height, size, seed)
    got = {}
    for e in takers(pixel):
        ev = rig.subscriber.wait_event("frame", lambda ev, e=e: ev["sha"] == digest and ev["pixel"] == e,
                                       timeout=30)
        got[e] = ev
        assert (ev["width"], ev["height"], ev["step"], ev["size"]) == (width, height, width * size,
                                                                       width * size * height), ev
        assert ev["is_bigendian"] == 0 and ev["frame_id"] == f"cam_{e}", ev
        assert ev["stamp"] == ns_of(stamp), (ev["stamp"], stamp)
    if "rgb8" in got:
        got["info"] = rig.subscriber.wait_event("info", lambda ev: ev["header"]["stamp"] == ns_of(stamp),
                                                timeout=30)
    return got


def calibration_info(c: dict) -> dict:
    """The CameraInfo fields of a calibration in iCub's format (plumb_bob)."""
    return {"width": c["w"], "height": c["h"], "distortion_model": "plumb_bob",
            "d": [c["k1"], c["k2"], c["p1"], c["p2"], 0.0],
            "k": [c["fx"], 0.0, c["cx"], 0.0, c["fy"], c["cy"], 0.0, 0.0, 1.0],
            "r": [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0],
            "p": [c["fx"], 0.0, c["cx"], 0.0, 0.0, c["fy"], c["cy"], 0.0, 0.0, 0.0, 1.0, 0.0]}


def check_camera_info(info: dict, width: int, height: int, calibration: dict = None,
                      frame_id: str = "cam_rgb8") -> None:
    """The calibration fitted to the frame's size: focal lengths and
    principal point scaled by the ratio of the sizes; the image's header."""
    c = calibration or calibration_info(CALIBRATION)
    sx, sy = width / c["width"], height / c["height"]
    k, p = list(c["k"]), list(c["p"])
    for i in (0, 2):
        k[i] *= sx
        p[i] *= sx
    k[4], k[5], p[5], p[6] = k[4] * sy, k[5] * sy, p[5] * sy, p[6] * sy
    assert (info["width"], info["height"]) == (width, height)
    assert info["header"]["frame_id"] == frame_id
    assert (info["distortion_model"], info["d"], info["r"]) == (c["distortion_model"], c["d"], c["r"])
    assert info["k"] == pytest.approx(k, rel=1e-15) and info["p"] == pytest.approx(p, rel=1e-15)
    assert (info["binning_x"], info["binning_y"]) == (0, 0)


@pytest.mark.parametrize("pixel", ENCODINGS)
def test_yarp_frame_to_ros2_image(yarp_to_ros2, pixel):
    """A 321x241 frame with padded rows: every pixel, step, encoding, the
    envelope's stamp; published by the nodes of its pixel type only."""
    got = send_yarp(yarp_to_ros2, W, H, pixel)
    assert sorted(k for k in got if k != "info") == sorted(takers(pixel))
    if pixel == "rgb8":
        check_camera_info(got["info"], W, H)
        assert got["info"]["header"]["stamp"] == got["rgb8"]["stamp"]


def test_yarp_resolution_changes_are_followed(yarp_to_ros2):
    """Frames of other sizes and paddings one after the other (quantum 1: no
    padding): each image its own size, the CameraInfo fitted to it."""
    for width, height, quantum in ((640, 480, 1), (160, 120, 8), (320, 240, 8), (W, H, 1), (7, 3, 8)):
        got = send_yarp(yarp_to_ros2, width, height, "rgb8", quantum)
        check_camera_info(got["info"], width, height)
    got = send_yarp(yarp_to_ros2, 64, 48, "mono16", 4)
    assert sorted(got) == ["16UC1", "mono16"]


def test_yarp_to_ros2_totals(yarp_to_ros2):
    """Stopped: each node received every frame written, refused those of
    another pixel type (said once), published the others."""
    rig = yarp_to_ros2
    time.sleep(0.3)  # a message published from a refused frame would be here by now
    total = sum(len(v) for v in rig.sent.values())
    for e, node in rig.nodes.items():
        log = stop_clean(node)
        mine = len(rig.sent.get(image_data.YARP_PIXELS[e], []))
        t = input_totals(log, YARP_SOURCE)
        assert (t["received"], t["dropped"], t["refused"], t["published"]) == (total, 0, total - mine, mine), \
            (e, t, log[-2000:])
        if total > mine:
            assert log.count("refused a frame") == 1, log[-2000:]
            assert f": the declared {e}" in t["why"], t
    # nothing published from a refused frame: one image per frame and node that takes it
    images = [ev for ev in rig.subscriber.events if ev["ev"] == "frame"]
    assert len(images) == sum(len(takers(p)) for v in rig.sent.values() for p in v)


# --------------------------------------------------------------------------
# ROS 2 -> YARP


@dataclass
class Ros2ToYarp:
    node: Node
    publisher: ImagePeer
    reader: ImagePeer
    sent: list = field(default_factory=list)   # encodings of the frames published
    seed: int = 2000
    written: int = 0  # frames the node writes: the count of the next one's envelope
    sent_at: float = 0.0  # time.time() before the last frame was published


@pytest.fixture(scope="module")
def ros2_to_yarp(yarp, tmp_path_factory):
    folder = tmp_path_factory.mktemp("ros2_to_yarp")
    config = folder / "ybg_camera.ini"
    config.write_text(f"[module]\nname = ybg_camera\n\n[mux cam]\ntopics = {ROS_TOPIC} (sensor_msgs/Image)\n"
                      f"via = ros2\n\n[output]\nport = {YARP_OUTPUT}\nimage = cam\n")
    path = generate(config, folder)
    started = []
    with YarpServer(install=yarp) as server, Ros2Domain() as domain:
        env = ros2_environment(server.env, domain)
        try:
            # every frame delivered, none overtaken (the inputs' default: best effort, the newest only)
            node = start_node(env, path, "--ros-args", "-p", "timeout:=120.0",
                              "-p", f"qos_overrides.{ROS_TOPIC}.subscription.reliability:=reliable",
                              "-p", f"qos_overrides.{ROS_TOPIC}.subscription.depth:=10")
            started.append(node)
            publisher = ImagePeer(env, {"mode": "ros2_pub", "topic": ROS_TOPIC}, name="image_publisher").start()
            started.append(publisher)
            node.wait_log("publishing camera images")
            reader = ImagePeer(env, {"mode": "yarp_sub", "port": YARP_READER, "connect_from": YARP_OUTPUT},
                               name="image_reader").start()
            started.append(reader)
            publisher.wait_event("matched", lambda ev: ev["n"] >= 1)
            node.wait_log(f"{ROS_TOPIC}: 1 publisher\n")
            yield Ros2ToYarp(node, publisher, reader)
        finally:
            for proc in reversed(started):
                proc.stop()


def send_ros2(rig: Ros2ToYarp, width: int, height: int, pixel: str, pad: int, stamped: bool = True) -> tuple:
    """One Image published with ``pad`` bytes after each row; its stamp
    (None: header.stamp left 0)."""
    rig.seed += 1
    stamp = [1_700_000_000 + rig.seed, 125_000_000 * (rig.seed % 8)] if stamped else None  # exact in a double
    rig.sent_at = time.time()
    rig.publisher.send(cmd="frame", width=width, height=height, pixel=pixel, seed=rig.seed, step_pad=pad,
                       stamp=stamp, frame_id="camera")
    rig.sent.append(pixel)
    return rig.seed, stamp


def receive_yarp(rig: Ros2ToYarp, width: int, height: int, pixel: str, seed: int, stamp: list | None) -> dict:
    """The frame the reader got: YARP's pixel type of the encoding (16UC1 is
    YARP's mono16), rows packed, every pixel; its envelope the node's count
    of frames and the image's stamp (none: the node's clock)."""
    size = image_data.PIXEL_SIZES[pixel]
    digest = image_data.sha(width, height, size, seed)
    ev = rig.reader.wait_event("frame", lambda ev: ev["sha"] == digest, timeout=30)
    assert ev["pixel"] == ("mono16" if pixel == "16UC1" else pixel), ev
    assert (ev["width"], ev["height"], ev["row_size"]) == (width, height, width * size), ev
    assert ev["stamp"] is not None and ev["stamp"][0] == rig.written, (ev["stamp"], rig.written)
    if stamp is not None:
        assert ev["stamp"][1] == stamp[0] + stamp[1] * 1e-9, (ev["stamp"], stamp)
    else:
        # the node's clock as it took the frame: after it was sent, before the reader had it
        # (YARP carries the time to 10 us: "Copies of a frame", docs/runtime.md)
        assert rig.sent_at - 1e-5 <= ev["stamp"][1] <= ev["t"] + 1e-5, (ev["stamp"], rig.sent_at, ev["t"])
    rig.written += 1
    return ev


ROS_ENCODINGS = ("rgb8", "bgr8", "rgba8", "bgra8", "mono8", "mono16", "16UC1", "32FC1")


@pytest.mark.parametrize("pixel", ROS_ENCODINGS)
def test_ros2_image_to_yarp_frame(ros2_to_yarp, pixel):
    """A 321x241 Image with rows padded in the message (step > width x
    pixel size): the YARP frame of its pixel type, every pixel, the stamp
    as its envelope."""
    seed, stamp = send_ros2(ros2_to_yarp, W, H, pixel, pad=3)
    receive_yarp(ros2_to_yarp, W, H, pixel, seed, stamp)


def test_ros2_resolution_changes_and_a_refused_encoding(ros2_to_yarp):
    """Sizes change from one message to the next; yuv422 (no YARP pixel
    type) is refused: nothing written, said once; an image with no stamp
    goes out with the node's time."""
    rig = ros2_to_yarp
    for width, height, pixel, pad in ((640, 480, "rgb8", 0), (7, 3, "rgb8", 1), (64, 48, "mono8", 64)):
        seed, stamp = send_ros2(rig, width, height, pixel, pad)
        receive_yarp(rig, width, height, pixel, seed, stamp)
    frames = sum(ev["ev"] == "frame" for ev in rig.reader.events)
    send_ros2(rig, W, H, "yuv422", 0)
    rig.node.wait_log("refused a frame (encoding yuv422, which YARP has no pixel type for)")
    seed, stamp = send_ros2(rig, W, H, "bgr8", 0, stamped=False)
    receive_yarp(rig, W, H, "bgr8", seed, stamp)
    assert sum(ev["ev"] == "frame" for ev in rig.reader.events) == frames + 1


def test_ros2_to_yarp_totals(ros2_to_yarp):
    rig = ros2_to_yarp
    log = stop_clean(rig.node)
    refused = rig.sent.count("yuv422")
    t = input_totals(log, ROS_TOPIC)
    assert (t["received"], t["dropped"], t["refused"], t["published"]) == \
        (len(rig.sent), 0, refused, len(rig.sent) - refused), (t, log[-2000:])
    assert log.count("refused a frame") == (1 if refused else 0)


# --------------------------------------------------------------------------
# the examples


EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


def example_program(stem: str):
    from ybg.backends import check_result
    from ybg.compiler.pipeline import compile_path

    result = check_result(compile_path(str(EXAMPLES / f"{stem}.ini")), "ros2")
    assert result.ok, "\n".join(str(d) for d in result.diagnostics)
    return result.program


def literal_fields(struct) -> dict:
    """The constants of a message the config gives: {field: value}."""
    from ybg.compiler import ir

    out = {}
    for f in struct.fields:
        if isinstance(f.source, ir.Literal):
            out[f.name] = list(f.source.values) if f.source.is_list else f.source.values[0]
    return out


@pytest.fixture(scope="module")
def examples_mw(yarp):
    with YarpServer(install=yarp) as server, Ros2Domain() as domain:
        yield ros2_environment(server.env, domain)


# the ROS 2 side of each example on today's YARP; every pixel type and every
# YARP release: the tests above
@pytest.mark.yarp_min((4, 0))
@pytest.mark.parametrize("stem", ["icub_left_eye_ros2", "rgbd_depth_ros2"])
def test_example_yarp_camera_to_ros2(examples_mw, tmp_path, stem):
    """The example as generated, its QoS made reliable for the subscriber:
    a frame at the calibration's size and one of twice that size, with their
    CameraInfo (from the calibration file, or the config's fields)."""
    program = example_program(stem)
    (mux,) = program.muxes
    (inp,) = mux.inputs
    out = program.output
    node_path = generate(EXAMPLES / f"{stem}.ini", tmp_path)
    qos = [f"qos_overrides.{topic}.publisher.reliability:=reliable" for topic in (out.name, out.camera_info.topic)]
    calibration = literal_fields(out.camera_info.message)
    frame_id = literal_fields(program.message.fields[0].source)["frame_id"]
    env = examples_mw
    started = []
    try:
        subscriber = ImagePeer(env, {"mode": "ros2_sub", "topic": out.name, "info_topic": out.camera_info.topic},
                               name=f"{stem}_subscriber").start()
        started.append(subscriber)
        node = start_node(env, node_path, "--ros-args", "-p", "timeout:=120.0",
                          *[x for q in qos for x in ("-p", q)])
        started.append(node)
        producer = ImagePeer(env, {"mode": "yarp_pub", "port": inp.name}, name=f"{stem}_producer").start()
        started.append(producer)
        node.wait_log(f"connected {inp.name} -> ")
        node.wait_log(f"{out.camera_info.topic}: 1 subscriber\n")
        subscriber.wait_event("matched", lambda ev: ev["n"] >= 1)
        size = image_data.PIXEL_SIZES[inp.image]
        for k, scale in enumerate((1, 2)):
            width, height = calibration["width"] * scale, calibration["height"] * scale
            stamp = 1_700_000_000.5 + k
            producer.send(cmd="frame", width=width, height=height, pixel=inp.image, seed=k, stamp=[k, stamp])
            digest = image_data.sha(width, height, size, k)
            ev = subscriber.wait_event("frame", lambda ev: ev["sha"] == digest, timeout=30)
            assert (ev["pixel"], ev["width"], ev["height"], ev["step"]) == (inp.image, width, height, width * size)
            assert (ev["stamp"], ev["frame_id"]) == (ns_of(stamp), frame_id)
            info = subscriber.wait_event("info", lambda ev: ev["header"]["stamp"] == ns_of(stamp), timeout=30)
            check_camera_info(info, width, height, calibration, frame_id)
        log = stop_clean(node)
    finally:
        for proc in reversed(started):
            proc.stop()
    t = input_totals(log, inp.name)
    assert (t["received"], t["refused"], t["published"]) == (2, 0, 2), t


@pytest.mark.yarp_min((4, 0))
def test_example_ros2_camera_to_yarp(examples_mw, tmp_path):
    program = example_program("ros2_camera_to_yarp")
    (inp,) = program.muxes[0].inputs
    node_path = generate(EXAMPLES / "ros2_camera_to_yarp.ini", tmp_path)
    env = examples_mw
    started = []
    try:
        node = start_node(env, node_path, "--ros-args",
                          "-p", f"qos_overrides.{inp.name}.subscription.reliability:=reliable")
        started.append(node)
        publisher = ImagePeer(env, {"mode": "ros2_pub", "topic": inp.name}, name="camera_publisher").start()
        started.append(publisher)
        node.wait_log("publishing camera images")
        reader = ImagePeer(env, {"mode": "yarp_sub", "port": "/ybg_camera/reader",
                                 "connect_from": program.output.name}, name="camera_reader").start()
        started.append(reader)
        publisher.wait_event("matched", lambda ev: ev["n"] >= 1)
        node.wait_log(f"{inp.name}: 1 publisher\n")
        publisher.send(cmd="frame", width=640, height=480, pixel="rgb8", seed=5, step_pad=0,
                       stamp=[1_700_000_000, 750_000_000])
        ev = reader.wait_event("frame", lambda ev: ev["sha"] == image_data.sha(640, 480, 3, 5), timeout=30)
        assert (ev["pixel"], ev["row_size"], ev["stamp"]) == ("rgb8", 1920, [0, 1_700_000_000.75])
        stop_clean(node)
    finally:
        for proc in reversed(started):
            proc.stop()
