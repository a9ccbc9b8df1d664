"""Camera image peer (venv python with the yarp bindings and rclpy): a YARP
image producer or reader, or a ROS 2 Image publisher or subscriber (with its
CameraInfo).

Config: {"mode": "yarp_pub" | "yarp_sub" | "ros2_pub" | "ros2_sub", "port" or "topic": name,
         "node": "ybg_image_peer", "info_topic": "/.../camera_info" (ros2_sub, optional),
         "connect_to": "/port" (yarp_pub, optional), "connect_from": "/port" (yarp_sub, optional)}
Commands (pub): {"cmd": "frame", "width": w, "height": h, "pixel": "rgb8" (a ROS encoding,
                  or "code:<n>" for a raw YARP pixel code), "seed": n, "quantum": q (yarp_pub, default 8),
                  "step_pad": k (ros2_pub: bytes added to each row, default 0),
                  "stamp": [sec, nanosec] (ros2) or [count, seconds] (yarp envelope), "frame_id": "..."}
                {"cmd": "quit"}
Events: ready; matched (n) (ros2 modes); sent (n);
        frame (width, height, pixel, step, row_size, sha (sha256 of the pixels without row padding),
               stamp, frame_id, is_bigendian) for what a sub mode receives;
        info (every CameraInfo field, header as {"stamp": [sec, nanosec], "frame_id"}).
The pixels of a frame are image_data.pixels(width, height, pixel size, seed): what
a test expects is computed from the same function.
"""
import ctypes
import hashlib
import os
import sys
import threading
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import image_data  # noqa: E402
import peer_io  # noqa: E402


def sha(rows: bytes, height: int, step: int, row_bytes: int) -> str:
    h = hashlib.sha256()
    for y in range(height):
        h.update(rows[y * step:y * step + row_bytes])
    return h.hexdigest()


def yarp_pub(cfg):
    import yarp
    yarp.Network.init()
    port = yarp.Port()
    port.setWriteOnly()
    if not port.open(cfg["port"]):
        peer_io.emit("error", message="cannot open " + cfg["port"])
        return 1
    if cfg.get("connect_to"):
        yarp.Network.connect(cfg["port"], cfg["connect_to"])
    peer_io.emit("ready")
    n = 0
    q = peer_io.commands()
    while True:
        c = q.get()
        if c is None or c.get("cmd") == "quit":
            port.close()
            return 0
        if c["cmd"] != "frame":
            continue
        w, h = int(c["width"]), int(c["height"])
        pixel = c.get("pixel", "rgb8")
        code = int(pixel[5:]) if pixel.startswith("code:") else image_data.yarp_code(yarp, pixel)
        size = image_data.PIXEL_SIZES.get(pixel, 3)
        img = yarp.FlexImage()
        img.setPixelCode(code)
        img.setQuantum(int(c.get("quantum", 8)))
        img.resize(w, h)
        raw = (ctypes.c_ubyte * img.getRawImageSize()).from_address(int(img.getRawImage()))
        src = image_data.pixels(w, h, size, int(c.get("seed", 0)))
        row = img.getRowSize()
        for y in range(h):
            ctypes.memmove(ctypes.addressof(raw) + y * row, src[y * w * size:(y + 1) * w * size], w * size)
        if c.get("stamp") is not None:
            port.setEnvelope(yarp.Stamp(int(c["stamp"][0]), float(c["stamp"][1])))
        port.write(img)
        peer_io.emit("sent", n=n)
        n += 1


def yarp_sub(cfg):
    import yarp
    yarp.Network.init()
    port = yarp.Port()
    port.setReadOnly()
    if not port.open(cfg["port"]):
        peer_io.emit("error", message="cannot open " + cfg["port"])
        return 1
    if cfg.get("connect_from"):
        yarp.Network.connect(cfg["connect_from"], cfg["port"])
    peer_io.exit_at_stdin_eof()
    peer_io.emit("ready")
    names = {image_data.yarp_code(yarp, p): p for p in image_data.PIXEL_SIZES if p not in ("16UC1",)}
    while True:
        img = yarp.FlexImage()
        if not port.read(img):
            continue
        st = yarp.Stamp()
        stamp = None
        if port.getEnvelope(st) and st.isValid():
            stamp = [st.getCount(), st.getTime()]
        w, h, ps, row = img.width(), img.height(), img.getPixelSize(), img.getRowSize()
        data = ctypes.string_at(int(img.getRawImage()), img.getRawImageSize())
        peer_io.emit("frame", width=w, height=h, pixel=names.get(img.getPixelCode(), img.getPixelCode()),
                     step=row, row_size=row, sha=sha(data, h, row, w * ps), stamp=stamp)


def ros2_node(cfg):
    import rclpy
    from rclpy.signals import SignalHandlerOptions
    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    return rclpy.create_node(cfg.get("node") or "ybg_image_peer")


def ros2_pub(cfg):
    from rclpy.executors import SingleThreadedExecutor
    from sensor_msgs.msg import Image
    node = ros2_node(cfg)
    pub = node.create_publisher(Image, cfg["topic"], int(cfg.get("depth") or 10))
    ex = SingleThreadedExecutor()
    ex.add_node(node)
    q = peer_io.commands()
    peer_io.emit("ready")
    matched, n = -1, 0
    import queue
    while True:
        ex.spin_once(timeout_sec=0.01)
        k = pub.get_subscription_count()
        if k != matched:
            matched = k
            peer_io.emit("matched", n=k)
        try:
            c = q.get_nowait()
        except queue.Empty:
            continue
        if c is None or c.get("cmd") == "quit":
            return 0
        if c["cmd"] != "frame":
            continue
        w, h = int(c["width"]), int(c["height"])
        pixel = c.get("pixel", "rgb8")
        size = image_data.PIXEL_SIZES.get(pixel, 3)
        pad = int(c.get("step_pad", 0))
        src = image_data.pixels(w, h, size, int(c.get("seed", 0)))
        step = w * size + pad
        rows = bytearray(step * h)
        for y in range(h):
            rows[y * step:y * step + w * size] = src[y * w * size:(y + 1) * w * size]
        msg = Image()
        msg.width, msg.height, msg.encoding, msg.step, msg.is_bigendian = w, h, pixel, step, 0
        msg.data = bytes(rows)
        msg.header.frame_id = c.get("frame_id", "")
        if c.get("stamp") is not None:
            msg.header.stamp.sec, msg.header.stamp.nanosec = int(c["stamp"][0]), int(c["stamp"][1])
        pub.publish(msg)
        peer_io.emit("sent", n=n)
        n += 1


def ros2_sub(cfg):
    from rclpy.executors import SingleThreadedExecutor
    from sensor_msgs.msg import CameraInfo, Image
    node = ros2_node(cfg)

    def on_image(msg):
        size = image_data.PIXEL_SIZES.get(msg.encoding, 1)
        data = bytes(msg.data)
        peer_io.emit("frame", width=msg.width, height=msg.height, pixel=msg.encoding, step=msg.step,
                     size=len(data), sha=sha(data, msg.height, msg.step, msg.width * size),
                     stamp=[msg.header.stamp.sec, msg.header.stamp.nanosec], frame_id=msg.header.frame_id,
                     is_bigendian=msg.is_bigendian)

    def on_info(msg):
        peer_io.emit("info", width=msg.width, height=msg.height, distortion_model=msg.distortion_model,
                     d=list(msg.d), k=list(msg.k), r=list(msg.r), p=list(msg.p),
                     binning_x=msg.binning_x, binning_y=msg.binning_y,
                     header={"stamp": [msg.header.stamp.sec, msg.header.stamp.nanosec],
                             "frame_id": msg.header.frame_id})

    subs = [node.create_subscription(Image, cfg["topic"], on_image, int(cfg.get("depth") or 10))]
    if cfg.get("info_topic"):
        subs.append(node.create_subscription(CameraInfo, cfg["info_topic"], on_info, int(cfg.get("depth") or 10)))
    ex = SingleThreadedExecutor()
    ex.add_node(node)
    peer_io.exit_at_stdin_eof()
    peer_io.emit("ready")
    matched = -1
    while True:
        ex.spin_once(timeout_sec=0.02)
        k = subs[0].get_publisher_count()
        if k != matched:
            matched = k
            peer_io.emit("matched", n=k)


def main():
    cfg = peer_io.config()
    peer_io.exit_on_signals()
    return {"yarp_pub": yarp_pub, "yarp_sub": yarp_sub, "ros2_pub": ros2_pub, "ros2_sub": ros2_sub}[cfg["mode"]](cfg)


if __name__ == "__main__":
    threading.current_thread().name = "image_peer"
    time.sleep(0)
    raise SystemExit(main())
