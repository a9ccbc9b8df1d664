"""The pixels of a test frame, the same in the peers that send them and in the
tests that check what arrives (stdlib only)."""
import hashlib

#: bytes per pixel of each ROS encoding the peers send
PIXEL_SIZES = {"rgb8": 3, "bgr8": 3, "rgba8": 4, "bgra8": 4, "mono8": 1, "mono16": 2, "16UC1": 2, "32FC1": 4}

#: the YARP pixel code (by its constant's name) of each encoding
YARP_PIXELS = {"rgb8": "VOCAB_PIXEL_RGB", "bgr8": "VOCAB_PIXEL_BGR", "rgba8": "VOCAB_PIXEL_RGBA",
               "bgra8": "VOCAB_PIXEL_BGRA", "mono8": "VOCAB_PIXEL_MONO", "mono16": "VOCAB_PIXEL_MONO16",
               "16UC1": "VOCAB_PIXEL_MONO16", "32FC1": "VOCAB_PIXEL_MONO_FLOAT"}


def yarp_code(yarp, encoding: str) -> int:
    return int(getattr(yarp, YARP_PIXELS[encoding]))


def pixels(width: int, height: int, size: int, seed: int) -> bytes:
    """width x height pixels of ``size`` bytes, packed rows, every byte a
    function of its place and ``seed`` (no two frames of different seeds or
    sizes alike)."""
    n = width * height * size
    out = bytearray(n)
    block = hashlib.sha256(b"%d %d %d %d" % (width, height, size, seed)).digest()
    for k in range(0, n, 32):
        block = hashlib.sha256(block).digest()
        out[k:k + 32] = block[:min(32, n - k)]
    return bytes(out)


def sha(width: int, height: int, size: int, seed: int) -> str:
    """The sha256 of the packed pixels of :func:`pixels`: what a reader that
    hashes the pixels row by row, without padding, finds."""
    return hashlib.sha256(pixels(width, height, size, seed)).hexdigest()
