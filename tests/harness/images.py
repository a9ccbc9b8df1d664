"""Camera images in the tests: the image peer (tests/peers/image_peer.py)
and the frames it sends, with their expected hashes (tests/peers/image_data.py)."""
from __future__ import annotations

import sys

from harness.env import PEERS
from harness.procs import Peer

sys.path.insert(0, str(PEERS))
import image_data  # noqa: E402  (the peers' pixels, for the expected hashes)

#: bytes per pixel of each encoding
SIZE = image_data.PIXEL_SIZES


class ImagePeer(Peer):
    """tests/peers/image_peer.py: a YARP image producer or reader, a ROS 2
    Image publisher or subscriber (with its CameraInfo)."""

    script = "image_peer.py"
    frames_sent = 0  # frame commands given (a producer sends each)

    def send(self, **cmd) -> None:
        super().send(**cmd)
        self.frames_sent += cmd.get("cmd") == "frame"

    def events_of(self, ev: str, since: int = 0) -> list:
        with self._cond:
            return [e for e in self.events[since:] if e["ev"] == ev]


def frame(width: int, height: int, pixel: str, seed: int, **extra) -> dict:
    """The command that makes a producer send one frame."""
    return {"cmd": "frame", "width": width, "height": height, "pixel": pixel, "seed": seed, **extra}


def sha_of(f: dict) -> str:
    """The hash of the pixels of frame command ``f``, as a reader finds them."""
    return image_data.sha(f["width"], f["height"], SIZE[f["pixel"]], f["seed"])
