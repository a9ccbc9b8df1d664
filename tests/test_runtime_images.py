"""The runtime's camera images (ybg/runtime/images.py, and the node's side of
them in ros2_io.py), tested as code: the pixel types (held to the IR's
table and to YARP's own constants), the row copies (odd widths, YARP's row
padding, a padded ROS step), the frames of ROS 2 messages and what is
refused, the calibration fitted to a frame, real yarp FlexImages with no
name server, real sensor_msgs messages with no ROS graph, and the bridge's
account of refused frames driven by hand (as tests/test_runtime.py drives
it). tests/test_images_ros2.py runs the nodes on real middleware."""

from __future__ import annotations

import argparse
import array
import ctypes

import pytest

from harness.bridges import hand_bridge
from ybg.compiler import ir
from ybg.runtime import core, images
from ybg.runtime.core import BridgeSpec, InputSpec, MuxSpec
from ybg.runtime.images import (PIXEL_TYPES, Frame, append_rows, copy_rows, fit_calibration, message_frame,
                                pixel_code, pixel_size, vocab32, vocab_text, yarp_frame)


def packed_rows(source, row_size, row_bytes, height):
    return append_rows(array.array("B"), source, row_size, row_bytes, height)


def pattern(n: int, salt: int = 0) -> bytes:
    return bytes((k * 7 + salt) % 251 for k in range(n))


# --------------------------------------------------------------------------
# pixel types


def test_pixel_types_are_the_irs_and_yarps():
    """Each encoding of the IR's table has the pixel code YARP's bindings
    name for it, and the size a FlexImage of that code has; 8UC1 is read
    as mono8; nothing else has a pixel type."""
    import yarp

    assert set(PIXEL_TYPES) == set(ir.IMAGE_ENCODINGS) | {"8UC1"}
    for encoding, (code, size, channel) in PIXEL_TYPES.items():
        constant = ir.IMAGE_ENCODINGS.get(encoding, "VOCAB_PIXEL_MONO")
        assert code == getattr(yarp, constant) == pixel_code(encoding), encoding
        image = yarp.FlexImage()
        image.setPixelCode(code)
        assert image.getPixelSize() == size == pixel_size(encoding), encoding
        assert size % channel == 0
    for other in ("yuv422", "bayer_rggb8", "rgb16", "", "RGB8"):
        assert pixel_code(other) is None


def test_vocab_codes_and_their_text():
    assert vocab32("rgb") == 6449010
    assert [vocab_text(PIXEL_TYPES[e][0]) for e in ("rgb8", "bgra8", "mono8", "mono16", "32FC1")] == \
        ["rgb", "bgra", "mono", "mo16", "dec"]
    assert vocab_text(0) == "0" and vocab_text(-3) == "-3"  # YARP's invalid code, a size without a code


# --------------------------------------------------------------------------
# row copies


@pytest.mark.parametrize("width,height,size,row_size", [
    (321, 241, 3, 968),   # YARP's quantum 8: 5 bytes of padding a row
    (321, 241, 1, 328),
    (321, 241, 4, 1288),
    (320, 240, 3, 960),   # no padding: one copy of the whole
    (7, 3, 2, 16),
    (1, 1, 4, 8),
])
def test_packed_rows_drop_the_padding(width, height, size, row_size):
    row_bytes = width * size
    source = bytearray(pattern(row_size * height))
    out = packed_rows(source, row_size, row_bytes, height)
    assert isinstance(out, array.array) and out.typecode == "B"
    assert out.tobytes() == b"".join(bytes(source[y * row_size:y * row_size + row_bytes]) for y in range(height))


def test_packed_rows_of_a_buffer_shorter_than_its_rows_is_an_error():
    with pytest.raises(ValueError):
        packed_rows(bytes(100), 10, 12, 5)  # rows longer than their spacing
    with pytest.raises(ValueError):
        packed_rows(bytes(39), 10, 10, 4)
    assert packed_rows(bytes(38), 10, 8, 4).tobytes() == bytes(32)  # the last row needs no padding
    assert len(packed_rows(b"", 0, 0, 0)) == 0


def test_rows_are_appended():
    out = array.array("B", b"ab")
    append_rows(out, b"123x456x", 4, 3, 2)
    append_rows(out, b"78", 2, 2, 1)
    assert out.tobytes() == b"ab12345678"


@pytest.mark.parametrize("src_step,dst_row", [(963, 963), (966, 963), (963, 968), (1024, 1000)])
def test_copy_rows_between_paddings(src_step, dst_row):
    width, height, size = 321, 241, 3
    row_bytes = width * size
    source = array.array("B", pattern(src_step * height, 3))
    destination = bytearray(dst_row * height)
    copy_rows(destination, dst_row, source, src_step, row_bytes, height)
    for y in range(height):
        row = source[y * src_step:y * src_step + row_bytes].tobytes()
        assert destination[y * dst_row:y * dst_row + row_bytes] == row
        assert not any(destination[y * dst_row + row_bytes:(y + 1) * dst_row])  # the padding untouched


def test_copy_rows_refuses_short_buffers():
    with pytest.raises(ValueError):
        copy_rows(bytearray(30), 10, bytes(29), 10, 10, 3)
    with pytest.raises(ValueError):
        copy_rows(bytearray(29), 10, bytes(30), 10, 10, 3)
    copy_rows(bytearray(0), 0, b"", 0, 0, 0)  # an empty frame: nothing to do


# --------------------------------------------------------------------------
# ROS 2 messages: frames and refusals


def test_message_frame_takes_the_messages_buffer():
    data = array.array("B", pattern(966 * 2))
    frame, why = message_frame(321, 2, "rgb8", 966, 0, data, 12.5)
    assert why is None and frame.data is data  # no copy
    assert (frame.width, frame.height, frame.encoding, frame.step, frame.stamp) == (321, 2, "rgb8", 966, 12.5)
    assert frame.row_bytes() == 963
    frame, why = message_frame(5, 1, "8UC1", 5, 0, bytes(5), None)
    assert why is None and pixel_code(frame.encoding) == pixel_code("mono8")


@pytest.mark.parametrize("fields,why", [
    ((4, 2, "yuv422", 8, 0, bytes(16)), "encoding yuv422, which YARP has no pixel type for"),
    ((4, 2, "", 8, 0, bytes(16)), "encoding '', which YARP has no pixel type for"),
    ((4, 2, "rgb8", 11, 0, bytes(22)), "step 11, shorter than a row of 4 rgb8 pixels"),
    ((4, 2, "mono16", 8, 0, bytes(15)), "15 bytes of data, fewer than step x height = 16"),
    ((4, 2, "mono16", 8, 1, bytes(16)), "big-endian mono16 pixels (YARP's are little-endian)"),
    ((4, 2, "32FC1", 16, 1, bytes(32)), "big-endian 32FC1 pixels (YARP's are little-endian)"),
    ((0, 2, "rgb8", 0, 0, b""), "no pixels (0x2)"),
    ((3, 0, "mono8", 3, 0, b""), "no pixels (3x0)"),
])
def test_message_frame_refusals(fields, why):
    assert message_frame(*fields, None) == (None, why)


def test_big_endian_bytes_are_bytes():
    frame, why = message_frame(4, 2, "rgb8", 12, 1, bytes(24), None)
    assert why is None and frame is not None


def test_a_frame_goes_out_with_the_counter_and_its_stamp():
    """The envelope of a frame a YARP port writes: the message counter, the
    image's header.stamp, else the message's time (as the C++ module)."""
    frame = Frame(1, 1, "mono8", 1, bytes(1), 12.5)
    ctx = core.Context({}, 7, {}, now_ns=3_000_000_000)
    assert images.frame_out([frame], ctx) == (frame, 7, 12.5)
    assert images.frame_out([Frame(1, 1, "mono8", 1, bytes(1))], ctx)[1:] == (7, 3.0)
    assert images.frame_out([frame], core.Context({}, 2**31 + 5, {}, 0))[1] == 6


def test_calibration_fitted_to_the_frame():
    k = [200.0, 0.0, 160.0, 0.0, 210.0, 120.0, 0.0, 0.0, 1.0]
    p = [200.0, 0.0, 160.0, 0.0, 0.0, 210.0, 120.0, 0.0, 0.0, 0.0, 1.0, 0.0]
    assert fit_calibration(k, p, 320, 240, 320, 240) == (k, p)
    assert fit_calibration(k, p, 0, 0, 640, 480) == (k, p)  # a calibration with no size
    k2, p2 = fit_calibration(k, p, 320, 240, 640, 360)
    assert k2 == [400.0, 0.0, 320.0, 0.0, 315.0, 180.0, 0.0, 0.0, 1.0]
    assert p2 == [400.0, 0.0, 320.0, 0.0, 0.0, 315.0, 180.0, 0.0, 0.0, 0.0, 1.0, 0.0]
    assert k == [200.0, 0.0, 160.0, 0.0, 210.0, 120.0, 0.0, 0.0, 1.0]  # not changed in place


# --------------------------------------------------------------------------
# yarp FlexImages (no name server)


@pytest.mark.parametrize("encoding", ["rgb8", "bgra8", "mono8", "mono16", "32FC1"])
@pytest.mark.parametrize("quantum", [8, 1])
def test_yarp_frame_of_a_flex_image(encoding, quantum):
    import yarp

    width, height = 321, 241
    image = yarp.FlexImage()
    image.setPixelCode(pixel_code(encoding))
    image.setQuantum(quantum)
    image.resize(width, height)
    row, n = image.getRowSize(), image.getRawImageSize()
    assert (row > width * pixel_size(encoding)) == (quantum == 8)
    raw = pattern(n, 11)
    ctypes.memmove(int(image.getRawImage()), raw, n)
    frame = yarp_frame(image, encoding)
    row_bytes = width * pixel_size(encoding)
    # a view of YARP's pixels, padding and all: no copy until a message is filled
    assert (frame.width, frame.height, frame.encoding, frame.step, frame.owner) == (width, height, encoding, row,
                                                                                    image)
    assert ctypes.addressof(frame.data) == int(image.getRawImage())
    packed = packed_rows(frame.data, frame.step, row_bytes, height)
    assert packed.tobytes() == b"".join(raw[y * row:y * row + row_bytes] for y in range(height))


def test_written_frame_is_packed_in_a_flex_image():
    """What the YARP image output writes: a padded ROS step into a FlexImage
    of quantum 1 (the output's own copy, without its port)."""
    width, height, step = 321, 5, 970
    data = array.array("B", pattern(step * height, 5))
    frame = Frame(width, height, "bgr8", step, data, 3.5)
    out = images.YarpImageOutput("/unused:o")
    image = out.image_of(frame)
    assert (image.width(), image.height(), image.getRowSize()) == (width, height, width * 3)
    assert vocab_text(image.getPixelCode()) == "bgr"
    got = ctypes.string_at(int(image.getRawImage()), image.getRawImageSize())
    assert got == b"".join(data[y * step:y * step + width * 3].tobytes() for y in range(height))
    assert out.image_of(Frame(width, height, "bgr8", step, data)) is image  # the same type and size: kept
    assert out.image_of(Frame(width, height, "rgb8", step, data)) is not image


# --------------------------------------------------------------------------
# the node's messages (real sensor_msgs classes, no ROS graph)


def test_fill_image_from_a_frame():
    from sensor_msgs.msg import Image

    from ybg.runtime.ros2_io import fill_image

    data = array.array("B", pattern(968 * 2))
    msg = Image()
    own = msg.data
    fill_image(msg, [Frame(321, 2, "rgb8", 968, data)], "rgb8")  # YARP's rows, 5 bytes of padding each
    assert (msg.height, msg.width, msg.encoding, msg.is_bigendian, msg.step) == (2, 321, "rgb8", 0, 963)
    assert msg.data is own and msg.data.tobytes() == data[:963].tobytes() + data[968:968 + 963].tobytes()
    fill_image(msg, [Frame(3, 1, "mono8", 3, b"xyz")], "8UC1")  # a message filled again: its data anew
    assert (msg.data.tobytes(), msg.step, msg.encoding) == (b"xyz", 3, "8UC1")
    with pytest.raises(IndexError):
        fill_image(msg, [], "rgb8")  # a mux with no frame: a build failure, counted


def test_camera_info_follows_the_image():
    from sensor_msgs.msg import CameraInfo, Image

    from ybg.runtime.ros2_io import CameraInfoOutput

    def calibration():
        m = CameraInfo()
        m.width, m.height, m.distortion_model = 320, 240, "plumb_bob"
        m.d = [0.1, 0.2, 0.0, 0.0, 0.0]
        m.k = [200.0, 0.0, 160.0, 0.0, 210.0, 120.0, 0.0, 0.0, 1.0]
        m.p = [200.0, 0.0, 160.0, 0.0, 0.0, 210.0, 120.0, 0.0, 0.0, 0.0, 1.0, 0.0]
        return m

    published = []
    info = CameraInfoOutput("/cam/camera_info", calibration)
    info.prepare()
    info.publisher = argparse.Namespace(publish=lambda m: published.append(
        (m.header.stamp.sec, m.header.stamp.nanosec, m.header.frame_id, m.width, m.height, list(m.k), list(m.p))))
    image = Image(width=640, height=480)
    image.header.stamp.sec, image.header.stamp.nanosec, image.header.frame_id = 7, 250, "eye"
    info.publish(image)
    image.width, image.height = 320, 240
    info.publish(image)
    assert published[0][:5] == (7, 250, "eye", 640, 480)
    assert published[0][5] == [400.0, 0.0, 320.0, 0.0, 420.0, 240.0, 0.0, 0.0, 1.0]
    assert published[0][6] == [400.0, 0.0, 320.0, 0.0, 0.0, 420.0, 240.0, 0.0, 0.0, 0.0, 1.0, 0.0]
    assert published[1][3:] == (320, 240, calibration().k.tolist(), calibration().p.tolist())


# --------------------------------------------------------------------------
# the bridge's account of refused frames


def image_bridge():
    eye = InputSpec("eye", 0, "/cam:o", "yarp", None, 1.0, image="rgb8")
    spec = BridgeSpec("cam", "cam.ini", ("cam",), (MuxSpec("eye", (eye,), (), False, None),),
                      ("eye",), None, "all", 64, "skip", "pass")
    options = argparse.Namespace(prefix="/cam", rate=None, timeout=None, verbose=False)
    published = []
    out = argparse.Namespace(port_name="/cam/image_raw", publish=published.append)
    b = hand_bridge(spec, options, out, lambda ctx: images.frame_of(ctx.values["eye"]))
    b.publishing = True
    return b, published


def test_refused_frames_are_received_refused_and_said_once():
    b, published = image_bridge()
    inp = b.mux_inputs["eye"][0]
    frame = Frame(2, 1, "rgb8", 6, array.array("B", bytes(6)), 5.0)
    b.on_refused(inp, "pixel type mono, not rgb: the declared rgb8")
    b.on_bottle(inp, [frame], None, 1.0, 5.0)
    b.on_refused(inp, "pixel type bgr, not rgb: the declared rgb8")
    assert published == [frame] and inp.state == "fresh"
    assert (inp.received, inp.dropped, inp.refused, inp.unfit) == (3, 0, 2, 2)
    assert b.logged == ["input /cam:o: refused a frame (pixel type mono, not rgb: the declared rgb8); "
                        "further frames refused are only counted"]
    assert b.totals()[0] == [("/cam:o", 3, 0, 0, 0, 2)]  # what `stats` and /diagnostics say
    assert ("  input /cam:o: received 3, dropped 0, stale periods 0, unused 0, refused 2 frames "
            "(pixel type mono, not rgb: the declared rgb8)") in b.totals_lines()
    b.on_foreign(inp, "/other:o")
    assert any("refused 3: 1 from /other:o, 2 frames (pixel type mono" in line for line in b.totals_lines())


def test_a_refused_frame_does_not_make_a_waiting_input_fresh():
    b, published = image_bridge()
    inp = b.mux_inputs["eye"][0]
    b.on_refused(inp, "encoding yuv422, which YARP has no pixel type for")
    assert inp.state == "waiting" and inp.arrival is None and published == []
