"""Camera images in the Python modules (the ros2 backend's node): a frame
and its pixel types, the copies of its rows and the camera calibration fit
to a frame's size (plain code, tested as it is), and the YARP side: an
input port that reads frames of any pixel type, an output port that writes
them (docs/runtime.md, "Images").

A frame is copied once, whole or row by row (no Python per pixel): from
YARP's image into the packed rows of a sensor_msgs/Image's data (YARP ->
ROS 2), or from a message's rows into a YARP image of packed rows (ROS 2 ->
YARP)."""

import collections
import ctypes
import threading
import time

import yarp

from .core import BACKLOG  # ybgc:runtime-import
from .yarp_inputs import _NO_ENVELOPE, Input  # ybgc:runtime-import


def vocab32(text):
    """YARP's code of a vocab of up to 4 characters (``createVocab32``)."""
    code = 0
    for k, c in enumerate(text):
        code |= ord(c) << (8 * k)
    return code


def vocab_text(code):
    """The characters of a YARP vocab code ('rgb', 'mo16'), for messages."""
    code = int(code)
    chars = []
    while code > 0 and len(chars) < 4:
        chars.append(chr(code & 0xFF))
        code >>= 8
    text = "".join(chars)
    return text if text and text.isprintable() else str(code)


#: each ROS encoding that YARP has a pixel type for: (YARP pixel code, bytes
#: per pixel, bytes per channel). The IR's ``IMAGE_ENCODINGS`` names the same
#: codes by their constants (a test holds them to it and to YARP's bindings);
#: 8UC1 is read from ROS 2 as mono8 (the same layout)
PIXEL_TYPES = {
    "rgb8": (vocab32("rgb"), 3, 1),
    "bgr8": (vocab32("bgr"), 3, 1),
    "rgba8": (vocab32("rgba"), 4, 1),
    "bgra8": (vocab32("bgra"), 4, 1),
    "mono8": (vocab32("mono"), 1, 1),
    "8UC1": (vocab32("mono"), 1, 1),
    "mono16": (vocab32("mo16"), 2, 2),
    "16UC1": (vocab32("mo16"), 2, 2),
    "32FC1": (vocab32("dec"), 4, 4),
}


def pixel_code(encoding):
    """The YARP pixel code of a ROS encoding, or None when YARP has none."""
    found = PIXEL_TYPES.get(encoding)
    return None if found is None else found[0]


def pixel_size(encoding):
    """Bytes per pixel of a ROS encoding YARP has a pixel type for."""
    return PIXEL_TYPES[encoding][1]


class Frame:
    """One camera image: ``height`` rows of ``width`` pixels in ``encoding``,
    each row ``step`` bytes of ``data`` (a buffer), its time ``stamp`` in
    seconds (None: none given); ``owner`` keeps the buffer's memory alive
    (a YARP image whose pixels ``data`` is a view of). Frames are the values
    of an image mux: its one element."""

    __slots__ = ("width", "height", "encoding", "step", "data", "stamp", "owner")

    def __init__(self, width, height, encoding, step, data, stamp=None, owner=None):
        self.width = width
        self.height = height
        self.encoding = encoding
        self.step = step
        self.data = data
        self.stamp = stamp
        self.owner = owner

    def row_bytes(self):
        """The bytes of one row's pixels (``step`` may hold more)."""
        return self.width * pixel_size(self.encoding)

    def __repr__(self):
        return "Frame(%dx%d %s, step %d%s)" % (self.width, self.height, self.encoding, self.step,
                                                "" if self.stamp is None else ", stamp %.9f" % self.stamp)


def frame_of(values):
    """The frame of an image mux's values (IndexError when it has none)."""
    return values[0]


#: a frame as a YARP port writes it: its envelope's count and time
FrameOut = collections.namedtuple("FrameOut", "frame count time")

#: the count of a YARP envelope (an int32) wraps after this
_COUNT_WRAP = 2147483647


def frame_out(values, ctx):
    """The frame of an image mux's values as the YARP image output writes
    it: the envelope's count is the message counter, its time the frame's
    stamp (a ROS 2 image's header.stamp), else the message's time."""
    frame = frame_of(values)
    return FrameOut(frame, ctx.counter % _COUNT_WRAP, ctx.seconds if frame.stamp is None else frame.stamp)


def append_rows(out, source, row_size, row_bytes, height):
    """Append to ``out`` (an ``array('B')``) the rows of a frame packed, each
    ``row_bytes`` long (what ROS calls step), from ``source`` (a buffer)
    whose rows are ``row_size`` bytes apart (YARP pads rows to its quantum):
    one copy, of the whole buffer at once when no row is padded (else the
    room is made first, zeros, then each row copied into it)."""
    if row_size < row_bytes:
        raise ValueError("rows of %d bytes are %d bytes apart" % (row_bytes, row_size))
    n = row_bytes * height
    view = memoryview(source).cast("B")
    if height and len(view) < row_size * (height - 1) + row_bytes:
        raise ValueError("%d bytes for %d rows of %d bytes, %d apart" % (len(view), height, row_bytes, row_size))
    if row_size == row_bytes:
        out.frombytes(view[:n])
        return out
    start = len(out)
    out.frombytes(bytes(n))  # calloc'd: no pass over the frame's bytes
    dst = memoryview(out)[start:]
    for y in range(height):
        dst[y * row_bytes:(y + 1) * row_bytes] = view[y * row_size:y * row_size + row_bytes]
    return out


def copy_rows(destination, dst_row, source, src_step, row_bytes, height):
    """Copy ``height`` rows of ``row_bytes`` from ``source`` (rows
    ``src_step`` apart: a ROS step may be padded) into ``destination``
    (rows ``dst_row`` apart); both buffers. One copy: whole when both are
    packed alike, else row by row."""
    dst = memoryview(destination).cast("B")
    src = memoryview(source).cast("B")
    if height == 0 or row_bytes == 0:
        return
    if len(src) < src_step * (height - 1) + row_bytes or len(dst) < dst_row * (height - 1) + row_bytes:
        raise ValueError("a buffer is shorter than its rows")
    if src_step == dst_row == row_bytes:
        n = row_bytes * height
        dst[:n] = src[:n]
        return
    for y in range(height):
        dst[y * dst_row:y * dst_row + row_bytes] = src[y * src_step:y * src_step + row_bytes]


def message_frame(width, height, encoding, step, is_bigendian, data, stamp):
    """(Frame, None) for a ROS 2 image's fields (``data`` the message's
    buffer, not copied), or (None, why it is refused): an encoding YARP has
    no pixel type for, big-endian pixels of more than one byte, no pixels,
    a step shorter than a row, fewer bytes than step x height."""
    found = PIXEL_TYPES.get(encoding)
    if found is None:
        return None, "encoding %s, which YARP has no pixel type for" % (encoding or "''")
    _code, size, channel = found
    if is_bigendian and channel > 1:
        return None, "big-endian %s pixels (YARP's are little-endian)" % encoding
    if width == 0 or height == 0:
        return None, "no pixels (%dx%d)" % (width, height)
    if step < width * size:
        return None, "step %d, shorter than a row of %d %s pixels" % (step, width, encoding)
    n = len(data)
    if n < step * height:
        return None, "%d bytes of data, fewer than step x height = %d" % (n, step * height)
    return Frame(width, height, encoding, step, data, stamp), None


def fit_calibration(k, p, width, height, frame_width, frame_height):
    """The intrinsics ``k`` (3x3) and projection ``p`` (3x4) of a camera
    calibrated at ``width`` x ``height``, for a frame of another size: the
    focal lengths and principal point scaled by the ratio of the sizes
    (lists of floats). Unchanged when the sizes agree or the calibration
    has no size."""
    k = [float(x) for x in k]
    p = [float(x) for x in p]
    if not width or not height or (frame_width == width and frame_height == height):
        return k, p
    sx = frame_width / float(width)
    sy = frame_height / float(height)
    for i in (0, 2):
        k[i] *= sx
        p[i] *= sx
    for i in (4, 5):
        k[i] *= sy
    for i in (5, 6):
        p[i] *= sy
    return k, p


# --- the YARP side -------------------------------------------------------------

def yarp_frame(image, encoding):
    """A Frame of ``image`` (a yarp FlexImage of at least one pixel) in
    ``encoding``: a view of its pixels, YARP's row padding and all (no
    copy: the image is the frame's, until a message is filled from it)."""
    n = image.getRawImageSize()
    raw = (ctypes.c_ubyte * n).from_address(int(image.getRawImage()))
    return Frame(image.width(), image.height(), encoding, image.getRowSize(), raw, owner=image)


class ImageInput(Input):
    """A YARP port of camera images, read like a port of Bottles (each frame
    with the port that sent it, foreign ports refused, the same queues and
    freshness) but of yarp::sig::Image frames of any pixel type: a frame of
    the declared encoding's pixel type is given to the bridge as the mux's
    one value (YARP's image itself, each read into a new one: no copy); a
    frame of another pixel type, or of no pixels, is refused, counted and
    said once."""

    def __init__(self, bridge, spec, local, timeout):
        Input.__init__(self, bridge, spec, local, timeout)
        self.encoding = spec.image
        self.code = pixel_code(spec.image)

    def read_item(self, connection):
        image = yarp.FlexImage()
        return image if image.read(connection) else None

    def read_envelope(self):
        envelope = Input.read_envelope(self)
        # a port keeps the last envelope it read: a frame without one does
        # not take the previous frame's
        self.port.setEnvelope(_NO_ENVELOPE)
        return envelope

    def _handle(self, image, now, envelope, behind):
        """In the input's thread: a frame of the declared pixel type given to
        the bridge; another one refused."""
        if self.bridge.stopping:
            return
        try:
            if behind > BACKLOG:
                self.bridge.on_skipped(self)
                return
            code = image.getPixelCode()
            if image.width() == 0 or image.height() == 0:
                self.bridge.on_refused(self, "a frame of no pixels")
                return
            if code != self.code:
                self.bridge.on_refused(self, "pixel type %s, not %s: the declared %s" % (
                    vocab_text(code), vocab_text(self.code), self.encoding))
                return
            frame = yarp_frame(image, self.encoding)
            frame.stamp = envelope
            self.bridge.on_bottle(self, [frame], None, now, envelope)
        except Exception as e:  # never a traceback out of the input's thread
            self.fail(e)


class YarpImageOutput:
    """Writes each frame (a FrameOut) on a YARP port as a yarp::sig::Image
    of the pixel type of its encoding, rows packed (quantum 1), with its
    envelope.
    A plain port (the bindings have no BufferedPort of FlexImage, and only a
    FlexImage carries BGR and BGRA) written by a thread of its own, so that
    the bridge never waits for a slow reader: a frame that comes while the
    previous one is being written replaces any frame still waiting."""

    kind = "yarp"

    def __init__(self, port_name, connect_to=None):
        self.port_name = port_name
        self.connect_to = connect_to
        self.port = yarp.Port()
        self.image = None
        self.written = 0
        self.replaced = 0  # frames never written: a newer one came first
        self.cond = threading.Condition(threading.Lock())
        self.next = None
        self.busy = False
        self.closing = False
        self.failed = None
        self.thread = None
        self.log = lambda text: print(text, flush=True)

    def open(self):
        self.port.setWriteOnly()
        if not self.port.open(self.port_name):
            return False
        self.thread = threading.Thread(target=self._run, name="image output " + self.port_name, daemon=True)
        self.thread.start()
        return True

    def connections(self):
        return [(self.port_name, self.connect_to)] if self.connect_to else []

    def describe(self):
        return "camera images on the YARP port %s" % self.port_name

    def publish(self, out):
        with self.cond:
            if self.next is not None:
                self.replaced += 1
            self.next = out
            self.cond.notify()

    def _run(self):
        while True:
            with self.cond:
                while self.next is None and not self.closing:
                    self.cond.wait()
                if self.closing:
                    return
                out, self.next = self.next, None
                self.busy = True
            try:
                self.write(out)
            except Exception as e:  # never a traceback out of its thread
                if self.failed is None:
                    self.failed = e
                    self.log("%s: cannot write a frame: %s: %s" % (self.port_name, type(e).__name__, e))
            finally:
                with self.cond:
                    self.busy = False
                    self.cond.notify_all()

    def write(self, out):
        """A FrameOut written with its envelope."""
        image = self.image_of(out.frame)
        self.port.setEnvelope(yarp.Stamp(out.count, out.time))
        self.port.write(image)
        self.written += 1

    def image_of(self, frame):
        """The frame copied into the port's image (made anew when the pixel
        type or the size changes: quantum 1 before resize, rows packed)."""
        code = pixel_code(frame.encoding)
        image = self.image
        if image is None or image.getPixelCode() != code or image.width() != frame.width \
                or image.height() != frame.height:
            image = yarp.FlexImage()
            image.setPixelCode(code)  # one of PIXEL_TYPES: never a code YARP does not know
            image.setQuantum(1)
            image.resize(frame.width, frame.height)
            self.image = image
        n = image.getRawImageSize()
        if n:
            raw = (ctypes.c_ubyte * n).from_address(int(image.getRawImage()))
            copy_rows(raw, image.getRowSize(), frame.data, frame.step, frame.row_bytes(), frame.height)
        return image

    def stalled(self, grace=0.2):
        """A frame is still being written after ``grace`` seconds (a reader
        that stalls): closing would wait for it."""
        deadline = time.monotonic() + grace
        with self.cond:
            while self.busy:
                left = deadline - time.monotonic()
                if left <= 0:
                    return True
                self.cond.wait(left)
        return False

    def close(self):
        with self.cond:
            self.closing = True
            self.cond.notify_all()
        self.port.interrupt()
        self.port.close()
        if self.thread is not None:
            self.thread.join(0.2)
