"""The calls a node of commands makes (services.py, docs/services.md): to a
YARP RPC port (``YarpCaller``: the calls to one port one after another, in
the order they came, by one thread, each within its own deadline) and to a
ROS 2 service (``Ros2Caller``). Every call ends by its deadline, with the
reply or the reason it has none.

Blocking YARP calls: ``yarp.Port`` lets the interpreter lock go in its
calls (on every YARP the tests run), so a thread waiting in ``write`` or
``read`` stops no other. A write waiting for a stopped server cannot be
interrupted (``interrupt`` and ``close`` wait for it): the client port is
opened with a timeout (``Port.setTimeout``, the longest of its services'),
after which YARP gives the write up and drops the connection; the caller
itself waits on a Python event until its own deadline, never longer."""

import collections
import threading
import time

import yarp


class _Call:
    __slots__ = ("command", "deadline", "done", "reply", "reason", "sent", "over")

    def __init__(self, command, deadline):
        self.command = command
        self.deadline = deadline
        self.done = threading.Event()
        self.reply = None
        self.reason = None
        self.sent = False   # taken by the caller's thread
        self.over = False   # answered (by the thread) or given up (by its caller)


class YarpCaller:
    """One YARP RPC port called by the node: one connection at a time,
    through its own port ``local`` (opened with ``timeout``, the longest of
    its services': YARP gives a write up after it). Calls are made one
    after another, in the order they came, by one thread; ``call`` returns
    by the call's deadline whatever the server does. After a failed call
    the port is closed and opened afresh, so that nothing of that call's
    connection is ever read as another's; the next call connects again."""

    def __init__(self, local, target, timeout, log):
        self.local, self.target = local, target  # its own port, and the port it calls
        self.timeout = timeout
        self.log = log
        self.port = None
        self.queue = collections.deque()
        self.cond = threading.Condition()
        self.stopping = False
        self.busy = False
        self.thread = threading.Thread(target=self._run, name="calls to " + target, daemon=True)

    # -- the port
    def open(self):
        port = yarp.Port()
        port.setTimeout(float(self.timeout))
        port.setOutputMode(True)
        port.setInputMode(False)
        if not port.open(self.local):
            return False
        self.port = port
        if not self.thread.is_alive():
            self.thread.start()
        return True

    def _fresh(self):
        """Close the port (after a failed call) and open a new one."""
        port, self.port = self.port, None
        if port is not None:
            port.close()
        if not self.stopping:
            if not self.open():
                self.log("cannot open the port %s again" % self.local)

    def _connected(self):
        port = self.port
        if port is None:
            return False
        if port.getOutputCount() > 0:
            return True
        style = yarp.ContactStyle()
        style.quiet = True
        return yarp.Network.connect(self.local, self.target, style)

    # -- calls
    def call(self, command, deadline, stop_event=None):
        """(reply, None) or (None, reason key): ``no_server``, ``timed_out``,
        ``waited`` (its whole timeout spent waiting for the calls before it),
        ``stopped`` (``stop_event`` set before the deadline)."""
        c = _Call(command, deadline)
        with self.cond:
            if self.stopping:
                return None, "stopped"
            self.queue.append(c)
            self.cond.notify_all()
        while True:
            left = deadline - time.monotonic()
            if left <= 0 or (stop_event is not None and stop_event.is_set()):
                break
            if c.done.wait(min(left, 0.1)):
                break
        with self.cond:
            if c.over:
                return c.reply, c.reason
            c.over = True  # given up: the thread drops its reply
            if stop_event is not None and stop_event.is_set() and time.monotonic() < deadline:
                try:
                    self.queue.remove(c)
                except ValueError:
                    pass
                return None, "stopped"
            if not c.sent:
                try:
                    self.queue.remove(c)
                except ValueError:
                    pass
                return None, "waited"
        # a server that left the name server while the call waited (it quit) is no
        # server, whether or not its leaving broke the connection before the deadline
        # (the C++ runtime says the same); one still registered did not answer in time
        return None, "timed_out" if self._registered() else "no_server"

    def _registered(self):
        try:
            return yarp.Network.queryName(self.target).isValid()
        except Exception:  # a name server that cannot be asked: as before, no answer in time
            return True

    def _run(self):
        while True:
            with self.cond:
                while not self.queue and not self.stopping:
                    self.cond.wait()
                if self.stopping:
                    return
                c = self.queue.popleft()
                if c.over:
                    continue
                if time.monotonic() >= c.deadline:
                    self._answer(c, None, "waited")
                    continue
                c.sent = True
                self.busy = True
            try:
                self._send(c)
            except Exception as e:  # never a traceback out of the thread
                self.log("calling %s: %s: %s" % (self.target, type(e).__name__, e))
                with self.cond:
                    self._answer(c, None, "no_server")
                self._fresh()
            finally:
                with self.cond:
                    self.busy = False
                    self.cond.notify_all()

    def _send(self, c):
        if not self._connected():
            with self.cond:
                self._answer(c, None, "timed_out" if time.monotonic() >= c.deadline else "no_server")
            self._fresh()
            return
        reply = yarp.Bottle()
        ok = self.port.write(c.command, reply)
        with self.cond:
            if ok:
                self._answer(c, reply, None)
                return
            self._answer(c, None, "timed_out" if time.monotonic() >= c.deadline else "no_server")
        self._fresh()

    def _answer(self, c, reply, reason):
        """Under the lock: the call's answer, unless its caller gave it up."""
        if not c.over:
            c.over = True
            c.reply, c.reason = reply, reason
        c.done.set()

    def stop(self):
        with self.cond:
            self.stopping = True
            for c in self.queue:
                c.done.set()
            self.cond.notify_all()

    def close(self):
        """Close the port (a write waiting for a stopped server keeps it open
        until YARP gives up: the node then unregisters its name)."""
        port = self.port
        if port is not None:
            port.close()


# --------------------------------------------------------------------------
# calling a ROS 2 service

class Ros2Caller:
    """A ROS 2 service called by the node: each call waits for a server up
    to its deadline, then for its response up to the deadline; a response
    that comes later is dropped (rclpy matches each response to its request)."""

    POLL = 0.01

    def __init__(self, node, srv_class, name, group):
        self.name = name
        self.client = node.create_client(srv_class, name, callback_group=group)

    def call(self, request, deadline, stop_event):
        """(response, None) or (None, reason key): ``no_server``, ``timed_out``,
        ``stopped`` (``stop_event`` set before the deadline)."""
        while not self.client.service_is_ready():
            if stop_event.is_set():
                return None, "stopped"
            if time.monotonic() >= deadline:
                return None, "no_server"
            time.sleep(self.POLL)
        done = threading.Event()
        future = self.client.call_async(request)
        future.add_done_callback(lambda f: done.set())
        while not done.is_set():
            left = deadline - time.monotonic()
            if left <= 0 or stop_event.is_set():
                break
            done.wait(min(left, 0.1))
        if not future.done():
            self.client.remove_pending_request(future)
            future.cancel()
            return None, "stopped" if stop_event.is_set() and time.monotonic() < deadline else "timed_out"
        try:
            return future.result(), None
        except Exception:
            return None, "timed_out"

