"""A stream bridge's checked program (:class:`Program`): YARP ports or ROS
topics in, through muxes and converters, one message out (the README's
pipeline of one bridge)::

    inputs (YARP ports or ROS topics) --> Mux (concatenate, in port order)
        --> converters (per element range) --> message tree --> Output
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import ClassVar, Union

from ybg.compiler.diagnostics import Span

IR_VERSION = 1

NUMERIC_TYPES = frozenset(
    {"int8", "uint8", "int16", "uint16", "int32", "uint32", "int64", "uint64",
     "float32", "float64", "byte", "char"}
)
INTEGER_TYPES = NUMERIC_TYPES - {"float32", "float64"}
FLOAT_TYPES = frozenset({"float32", "float64"})
ELEMENT_TYPES = NUMERIC_TYPES | {"bool", "string"}
#: the encodings of camera images (sensor_msgs/Image, REP 118 for depth) that
#: YARP has a pixel type for: encoding -> the YARP pixel code's name
IMAGE_ENCODINGS: dict[str, str] = {
    "rgb8": "VOCAB_PIXEL_RGB", "bgr8": "VOCAB_PIXEL_BGR", "rgba8": "VOCAB_PIXEL_RGBA",
    "bgra8": "VOCAB_PIXEL_BGRA", "mono8": "VOCAB_PIXEL_MONO", "mono16": "VOCAB_PIXEL_MONO16",
    "16UC1": "VOCAB_PIXEL_MONO16", "32FC1": "VOCAB_PIXEL_MONO_FLOAT",
}
#: what a config may write for a pixel type: YARP's names, and the encodings
PIXEL_NAMES: dict[str, str] = {
    **{e: e for e in IMAGE_ENCODINGS},
    "rgb": "rgb8", "bgr": "bgr8", "rgba": "rgba8", "bgra": "bgra8", "mono": "mono8",
    "float": "32FC1", "PixelRgb": "rgb8", "PixelBgr": "bgr8", "PixelRgba": "rgba8", "PixelBgra": "bgra8",
    "PixelMono": "mono8", "PixelMono16": "mono16", "PixelFloat": "32FC1",
}
#: an image input of ROS 2: each message's own encoding
ANY_ENCODING = "any"
#: the message a camera frame fills, and the fields its frame gives besides `data`
IMAGE_TYPE = "sensor_msgs/Image"
FRAME_FIELDS = ("height", "width", "encoding", "is_bigendian", "step")

#: the element type of an undeclared port's elements in an untyped Bottle:
#: each as it came (an integer stays an integer)
NUMBER = "number"
#: what an element of an untyped Bottle may be
BOTTLE_ELEMENT_TYPES = ELEMENT_TYPES | {NUMBER}


# --------------------------------------------------------------------------
# Inputs and muxes


@dataclass(frozen=True)
class ElementGroup:
    """``count`` consecutive elements of one ``type`` in an input Bottle."""

    type: str
    count: int


@dataclass(frozen=True)
class Input:
    """One input of a mux.

    ``kind``: ``"yarp"`` a YARP port; ``"ros1"`` a ROS 1 topic read through
    YARP (``topic@/node``); ``"ros2"`` a ROS 2 topic (``ros_type`` required).
    ``layout`` is the declared element groups, or ``None`` when undeclared:
    then every element is taken as ``float64`` and the width is dynamic.
    ``fields`` (ROS inputs with a known type) names the numeric leaves of the
    message, in order, that make up the elements (``"x"``, ``"pose.position.x"``).
    ``positions`` (ROS 1 inputs with ``fields``): where each field sits in the
    message definition, as an index path (``point.x`` of
    ``geometry_msgs/PointStamped`` is ``(1, 0)``; a one-field array input is
    the path of the array). A backend reading the topic through YARP finds
    each field there in the Bottle, which YARP lays out like the definition.
    ``each`` (ROS 2 inputs): an array of messages of the message (``points``
    of ``trajectory_msgs/JointTrajectory``); ``fields`` are then fields of
    its elements, and each element gives one row of the mux (a time or
    duration as one float64, seconds).
    ``accepts`` (YARP ports): the other ports whose Bottles this input takes
    too (a replay under another name); a Bottle from any other port than
    ``name`` and these is refused at run time (docs/runtime.md, "Reading").
    ``qos`` (ROS 2 topics): the QoS its mux subscribes with, when the config
    gives one (``reliability``, ``durability``, ``depth`` in the mux); None:
    :data:`INPUT_QOS`.
    ``image``: a camera image input, not a Bottle: for a YARP port, the
    encoding its frames are declared in (:data:`IMAGE_ENCODINGS`: a frame of
    another pixel type is refused at run time); for a ROS 2
    ``sensor_msgs/Image`` topic, :data:`ANY_ENCODING`. It has no layout.
    """

    name: str
    kind: str = "yarp"
    layout: tuple[ElementGroup, ...] | None = None
    ros_type: str | None = None
    fields: tuple[str, ...] | None = None
    timeout: float = 1.0
    positions: tuple[tuple[int, ...], ...] | None = None
    reads: int | None = None
    each: str | None = None
    accepts: tuple[str, ...] = ()
    image: str | None = None
    qos: "QoS | None" = None
    span: Span | None = field(default=None, compare=False, repr=False)

    @property
    def subscription_qos(self) -> "QoS":
        """The QoS a ROS 2 input subscribes with: its mux's, else :data:`INPUT_QOS`."""
        return self.qos if self.qos is not None else INPUT_QOS

    @property
    def width(self) -> int | None:
        if self.layout is None:
            return None
        return sum(g.count for g in self.layout)

    @property
    def element_types(self) -> tuple[str, ...] | None:
        if self.layout is None:
            return None
        return tuple(g.type for g in self.layout for _ in range(g.count))


@dataclass(frozen=True)
class Converter:
    """A converter applied to the elements ``[start, stop)`` of a mux output.

    Every converter is ``y = x * scale + offset`` (``cast`` only: ``float64(x)``).
    ``name`` keeps what the user wrote (``deg_to_rad``, ``scale``, ...) for
    comments and verbose output. ``stop`` ``None`` means to the end.
    ``to_float``: the result is ``float64`` whatever the input type.
    """

    name: str
    scale: float = 1.0
    offset: float = 0.0
    to_float: bool = True
    start: int = 0
    stop: int | None = None
    span: Span | None = field(default=None, compare=False, repr=False)

    @property
    def is_identity(self) -> bool:
        return self.scale == 1.0 and self.offset == 0.0 and not self.to_float


@dataclass(frozen=True)
class GeometryKind:
    """What the checker and every backend know of one geometry converter:
    the elements it takes and gives, whether its last four results are a
    quaternion, and how a hint writes it. Adding a geometry converter is an
    entry here, its function in the runtime (``ybg/runtime/geometry.py``,
    whose widths a test holds to these) and in the C++ runtime (the
    ``ybgc::Geometry`` enumerator named by :attr:`cpp_name`), and its line
    in docs/config.md."""

    width_in: int
    width_out: int
    quaternion: bool
    example: str


#: the geometry converters, by name
GEOMETRY: dict[str, GeometryKind] = {
    "euler_to_quat": GeometryKind(3, 4, True, "euler_to_quat(xyz, deg)[0:3]"),
    "quat_to_euler": GeometryKind(4, 3, False, "quat_to_euler(xyz, rad)[3:7]"),
    "axis_angle_to_quat": GeometryKind(4, 4, True, "axis_angle_to_quat[3:7]"),
    "quat_to_axis_angle": GeometryKind(4, 4, False, "quat_to_axis_angle[3:7]"),
    "matrix_to_quat": GeometryKind(9, 4, True, "matrix_to_quat[0:9]"),
    "transform_to_pose": GeometryKind(16, 7, True, "transform_to_pose[0:16]"),
    "quat_normalize": GeometryKind(4, 4, True, "quat_normalize[3:7]"),
}
#: geometry converter -> (elements it takes, elements it gives)
GEOMETRY_WIDTHS: dict[str, tuple[int, int]] = {name: (g.width_in, g.width_out) for name, g in GEOMETRY.items()}
#: the converters whose results are a quaternion at their last four elements
QUATERNION_RESULTS = frozenset(name for name, g in GEOMETRY.items() if g.quaternion)
#: Euler axis orders (fixed axes, the first rotation first); ROS's rpy is xyz
EULER_AXES = ("xyz", "xzy", "yxz", "yzx", "zxy", "zyx")


@dataclass(frozen=True)
class GeometryConverter:
    """A vector-valued converter: the elements ``[start, start + width_in)``
    become its ``width_out`` results (float64), and the mux's width changes
    by the difference. ``axes`` and ``degrees``: the Euler converters' axis
    order and unit. ``text`` is what the user wrote, for comments."""

    name: str
    start: int
    axes: str | None = None
    degrees: bool = False
    text: str = ""
    span: Span | None = field(default=None, compare=False, repr=False)

    @property
    def width_in(self) -> int:
        return GEOMETRY_WIDTHS[self.name][0]

    @property
    def width_out(self) -> int:
        return GEOMETRY_WIDTHS[self.name][1]

    @property
    def stop(self) -> int:
        """The end of the elements it gives (``[start, stop)`` after it)."""
        return self.start + self.width_out


@dataclass(frozen=True)
class ExprNode:
    """A node of a checked element-wise expression. ``op``: ``"number"``
    (``value``), ``"x"`` (the element), ``"pi"``, ``"neg"`` (one operand),
    ``"+" "-" "*" "/"`` (two), or a function (``EXPR_FUNCTIONS``) with its
    ``args``."""

    op: str
    args: tuple["ExprNode", ...] = ()
    value: float | None = None


#: expression function -> number of arguments
EXPR_FUNCTIONS: dict[str, int] = {
    "abs": 1, "min": 2, "max": 2, "clamp": 3, "sqrt": 1, "sin": 1, "cos": 1, "atan2": 2,
}


@dataclass(frozen=True)
class ExprConverter:
    """An element-wise expression: each element x of ``[start, stop)``
    becomes ``body`` (float64). ``text`` is the expression as written
    (canonical form), for comments."""

    body: ExprNode
    start: int = 0
    stop: int | None = None
    text: str = ""
    span: Span | None = field(default=None, compare=False, repr=False)

    @property
    def name(self) -> str:
        return f"expr({self.text})"


AnyConverter = Union[Converter, GeometryConverter, ExprConverter]


@dataclass(frozen=True)
class Mux:
    """Concatenation of its inputs' elements, in input order, then converted.

    ``element_types`` and ``width`` are *after* conversion (``None``: dynamic
    width; elements then all numbers). ``verbose`` prints every value after
    conversion.
    """

    name: str
    inputs: tuple[Input, ...]
    converters: tuple[AnyConverter, ...] = ()
    verbose: bool = False
    span: Span | None = field(default=None, compare=False, repr=False)

    @property
    def image(self) -> str | None:
        """The encoding of the mux's frames when it is an image mux (its one
        input a camera image), else None."""
        return self.inputs[0].image if len(self.inputs) == 1 else None

    @property
    def rows(self) -> bool:
        """Does the mux hold one row per element of an array of messages
        (an input with ``each``), each row converted alike?"""
        return any(i.each is not None for i in self.inputs)

    @property
    def input_width(self) -> int | None:
        """The number of elements before the converters (of each row, for a
        mux of rows)."""
        widths = [i.width for i in self.inputs]
        if any(w is None for w in widths):
            return None
        return sum(widths)  # type: ignore[arg-type]

    @property
    def width(self) -> int | None:
        """The number of elements after the converters."""
        types = self.element_types
        return None if types is None else len(types)

    @property
    def element_types(self) -> tuple[str, ...] | None:
        """Element types after the converters (None when the width is dynamic)."""
        raw: list[str] = []
        for i in self.inputs:
            et = i.element_types
            if et is None:
                return None
            raw.extend(et)
        for c in self.converters:
            if isinstance(c, GeometryConverter):
                raw[c.start:c.start + c.width_in] = ["float64"] * c.width_out
            elif isinstance(c, ExprConverter) or c.to_float:
                stop = len(raw) if c.stop is None else c.stop
                for k in range(c.start, min(stop, len(raw))):
                    raw[k] = "float64"
        return tuple(raw)


# --------------------------------------------------------------------------
# The message tree


@dataclass(frozen=True)
class TypeRef:
    """The ROS type of a field: ``base`` is a primitive (``float64``, ``string``,
    ``time``, ``duration``) or a message (``std_msgs/Header``).

    ``array``: ``None`` scalar, ``"fixed"`` ``T[size]``, ``"sequence"`` ``T[]`` or
    ``T[<=size]`` (``size`` the bound, ``None`` unbounded).
    """

    base: str
    array: str | None = None
    size: int | None = None

    @property
    def is_message(self) -> bool:
        return "/" in self.base

    def element(self) -> "TypeRef":
        return TypeRef(self.base)

    def __str__(self) -> str:
        if self.array is None:
            return self.base
        if self.array == "fixed":
            return f"{self.base}[{self.size}]"
        return f"{self.base}[<={self.size}]" if self.size is not None else f"{self.base}[]"


@dataclass(frozen=True)
class Literal:
    """A constant. ``values`` has one item for a scalar; ``is_list`` makes it a
    list (possibly empty). ``element_type`` is the ROS primitive each value is
    sent as (``string``, ``float64``, ``int32``, ``bool`` ...)."""

    values: tuple[Union[str, int, float, bool], ...]
    element_type: str
    is_list: bool = False


@dataclass(frozen=True)
class MuxRef:
    """Elements ``[start, stop)`` of a mux after conversion.

    ``splice``: the elements are appended one by one into the enclosing list
    (legacy untyped YARP output); otherwise they form one nested list, or fill
    the fields of a nested message when ``into_fields`` names them (a mux of
    width 3 into ``geometry_msgs/Point``: ``("x", "y", "z")``).
    ``index``: a single element (``arm[3]``), sent as a scalar.
    ``element_type``: the ROS primitive of the elements; in an untyped Bottle
    also ``"number"`` (an undeclared port's elements, each written as it came:
    an integer as an integer, a real as a float64) or ``"mixed"``.
    """

    mux: str
    start: int = 0
    stop: int | None = None
    index: int | None = None
    splice: bool = False
    element_type: str = "float64"
    into_fields: tuple[str, ...] | None = None
    into_types: tuple[str, ...] | None = None


@dataclass(frozen=True)
class Counter:
    """Loop iterations published so far (0, 1, 2, ...), as ``element_type``."""

    element_type: str = "uint32"


@dataclass(frozen=True)
class Timestamp:
    """A ROS time: ``clock`` ``"wall"`` (node clock for ROS 2, sim time respected)
    or ``"envelope"`` (the newest YARP envelope stamp of ``mux``'s inputs,
    falling back to the wall clock when an input has none).
    ``style``: ``"ros1"`` ``(sec nsec)``, ``"ros2"`` ``builtin_interfaces/Time``
    ``(sec nanosec)``; on the wire both are two integers."""

    clock: str = "wall"
    mux: str | None = None
    style: str = "ros1"


@dataclass(frozen=True)
class Seconds:
    """Wall-clock time in seconds as one float64 (legacy untyped timestamp)."""


@dataclass(frozen=True)
class Default:
    """Not set by the config: ``value`` is the default the ``.msg`` gives
    (ROS 2 ``float64 w 1.0``; a tuple for an array), else ``None`` for the
    type's own default (0, false, "", empty list, a fixed array of those,
    time 0). A nested message left unset is a :class:`Struct` of defaults."""

    value: Union[str, int, float, bool, tuple, None] = None


@dataclass(frozen=True)
class MessageArray:
    """An array of messages of ``msg_type`` with as many elements as the
    config gives (``transforms[0].child_frame_id = ...``; a fixed-size array
    has its size). Each element is a :class:`Struct`, or a :class:`MuxRef`
    filling the element's numeric fields (``points[0] = goal``)."""

    elements: tuple[Union["Struct", MuxRef], ...]
    msg_type: str


@dataclass(frozen=True)
class ImageFrame:
    """The frame of the image mux ``mux``, in ``encoding``: the source of the
    ``data`` of a ``sensor_msgs/Image``, which gives its ``height``,
    ``width``, ``encoding``, ``is_bigendian`` and ``step`` too (those fields
    are left :class:`Default`: a backend fills all six from the frame)."""

    mux: str
    encoding: str


Source = Union[Literal, MuxRef, Counter, Timestamp, Seconds, Default, "Struct", MessageArray, ImageFrame]


@dataclass(frozen=True)
class Field:
    """One field of a message, or one item of an untyped YARP Bottle.

    ``type`` is ``None`` for untyped Bottles. ``name`` is the ROS field name,
    or the user's label in an untyped Bottle."""

    name: str
    source: Source
    type: TypeRef | None = None
    span: Span | None = field(default=None, compare=False, repr=False)


@dataclass(frozen=True)
class Struct:
    """A (nested) message: on the wire a nested list of its fields in order.

    ``msg_type`` is ``pkg/Name`` or ``None`` for an untyped Bottle."""

    fields: tuple[Field, ...]
    msg_type: str | None = None
    span: Span | None = field(default=None, compare=False, repr=False)


# --------------------------------------------------------------------------
# Output, timing, policies


#: the reliability and durability policies a config can name (the checker's
#: words for the keys, and what every runtime can make)
RELIABILITIES = ("reliable", "best_effort")
DURABILITIES = ("volatile", "transient_local")


@dataclass(frozen=True)
class QoS:
    reliability: str = "reliable"  # one of RELIABILITIES
    durability: str = "volatile"  # one of DURABILITIES
    depth: int = 10


#: The QoS of a ROS 2 output whose config gives none (each key given
#: replaces its policy): reliable, volatile, the last 10 messages kept.
OUTPUT_QOS = QoS("reliable", "volatile", 10)
#: The same for an output of sensor data (a camera, a laser, a point cloud,
#: an IMU: the output pass's SENSOR_DATA_TYPES), as ROS's sensor-data
#: profile (rclpy's qos_profile_sensor_data): best effort, depth 5.
SENSOR_DATA_QOS = QoS("best_effort", "volatile", 5)

#: The QoS of a ROS 2 input whose mux gives none: best effort and volatile,
#: the last message kept (a bridge publishes the latest values): it matches
#: every publisher's QoS.
INPUT_QOS = QoS("best_effort", "volatile", 1)
#: The depth of a ROS 2 input whose mux asks `reliability = reliable` and
#: gives no `depth` (as ROS's default profile keeps)
RELIABLE_INPUT_DEPTH = 10


@dataclass(frozen=True)
class CameraInfo:
    """A ``sensor_msgs/CameraInfo`` published on ``topic`` beside each image,
    with the image's header. ``message``: its fields (its ``header`` left
    :class:`Default`); when its ``width`` and ``height`` are set and a frame
    has another size, the run time scales the focal lengths and principal
    point of ``k`` and ``p`` to the frame and publishes the frame's size."""

    topic: str
    message: "Struct"
    span: Span | None = field(default=None, compare=False, repr=False)


@dataclass(frozen=True)
class Output:
    """Where the message goes.

    ``kind``: ``"yarp"`` a YARP port named ``name``; ``"ros1"`` a ROS 1 topic
    through YARP's bridge, port ``{name}@{node}``; ``"ros2"`` a ROS 2 topic.
    ``msg_type`` is ``pkg/Name`` (ROS 1 spelling also for ROS 2; backends add
    ``/msg/``); ``None`` for an untyped Bottle. ``connect_to`` (YARP only): a
    port of another module that the output connects to, and reconnects to when
    it reappears (legacy ``from_ros_topics``: ``output_name`` is that port)."""

    kind: str
    name: str
    msg_type: str | None = None
    node: str | None = None
    qos: QoS | None = None
    connect_to: str | None = None
    #: a YARP port of camera images: the image mux whose frames it writes
    image: str | None = None
    #: a ROS 2 image's camera calibration, published beside it
    camera_info: CameraInfo | None = None
    span: Span | None = field(default=None, compare=False, repr=False)
    #: where the message type is written (else the output's line)
    type_span: Span | None = field(default=None, compare=False, repr=False)


#: Bottles each input keeps that no message used yet, unless the config says
DEFAULT_QUEUE = 64
#: [output]'s policies when the config does not choose: publish once every
#: input delivered (``trigger``), nothing while an input is stale
#: (``on_stale``), NaN passed on (``on_nan``)
DEFAULT_TRIGGER = "all"
DEFAULT_ON_STALE = "skip"
DEFAULT_ON_NAN = "pass"


@dataclass(frozen=True)
class Timing:
    """``rate`` in Hz for a fixed period, or ``None`` for event-driven:
    publish when every input the message needs has delivered new data since
    the last publish (``trigger = "all"``) or any of them (``"any"``).
    ``queue``: the Bottles each input keeps that no message used yet; 1 is
    the newest only, read non-strictly (YARP's default). ``publish``, at a
    fixed rate: ``"always"`` every cycle, with the newest values (a state
    stream), or ``"new"`` only in a cycle where the trigger holds, new data
    as event-driven (commands: a goal is sent once, not at the rate)."""

    rate: float | None = None
    trigger: str = DEFAULT_TRIGGER
    queue: int = DEFAULT_QUEUE
    publish: str = "always"


@dataclass(frozen=True)
class Policy:
    """Run-time policies.

    ``on_stale``: ``"skip"`` publish nothing while an input is stale and say so
    once; ``"hold"`` publish with the last values. ``on_nan``: ``"pass"`` NaN
    goes out as is; ``"drop"`` an input Bottle holding NaN is dropped and counted.
    """

    on_stale: str = DEFAULT_ON_STALE
    on_nan: str = DEFAULT_ON_NAN


@dataclass(frozen=True)
class Program:
    """A checked stream bridge, ready for any backend."""

    #: its kind of bridge (ybg.compiler.ir.BRIDGE_KINDS)
    kind: ClassVar[str] = "stream"

    module: str
    source: str
    muxes: tuple[Mux, ...]
    message: Struct
    output: Output
    timing: Timing = Timing()
    policy: Policy = Policy()
    ros: str | None = None  # "ros1" | "ros2" | None (untyped)
    distro: str | None = None  # "noetic", "jazzy", ...

    def mux(self, name: str) -> Mux:
        for m in self.muxes:
            if m.name == name:
                return m
        raise KeyError(name)

    @property
    def span(self) -> Span | None:
        """Where the config writes the bridge, for what is said of it as a
        whole (its module, its RPC port): its output."""
        return self.output.span


__all__ = [
    "IR_VERSION",
    "NUMERIC_TYPES",
    "INTEGER_TYPES",
    "FLOAT_TYPES",
    "ELEMENT_TYPES",
    "IMAGE_ENCODINGS",
    "PIXEL_NAMES",
    "ANY_ENCODING",
    "IMAGE_TYPE",
    "FRAME_FIELDS",
    "NUMBER",
    "BOTTLE_ELEMENT_TYPES",
    "ElementGroup",
    "Input",
    "Converter",
    "GeometryKind",
    "GEOMETRY",
    "GEOMETRY_WIDTHS",
    "QUATERNION_RESULTS",
    "EULER_AXES",
    "GeometryConverter",
    "ExprNode",
    "EXPR_FUNCTIONS",
    "ExprConverter",
    "AnyConverter",
    "Mux",
    "TypeRef",
    "Literal",
    "MuxRef",
    "Counter",
    "Timestamp",
    "Seconds",
    "Default",
    "MessageArray",
    "ImageFrame",
    "Source",
    "Field",
    "Struct",
    "RELIABILITIES",
    "DURABILITIES",
    "QoS",
    "OUTPUT_QOS",
    "SENSOR_DATA_QOS",
    "INPUT_QOS",
    "RELIABLE_INPUT_DEPTH",
    "CameraInfo",
    "Output",
    "DEFAULT_QUEUE",
    "DEFAULT_TRIGGER",
    "DEFAULT_ON_STALE",
    "DEFAULT_ON_NAN",
    "Timing",
    "Policy",
    "Program",
]
