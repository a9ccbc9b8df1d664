"""The runtime library of the Python modules ybgc generates.

A generated module holds what its config says (the spec tables, the message
builder, the user blocks, ``main``); the behaviour lives here, as plain code
with its own tests:

- :mod:`.core`: the logic, with no middleware: inputs' queues and
  freshness, matching Bottles into messages, converters, timing, totals;
- :mod:`.yarp_io`: YARP ports, input Bottles checked, the output Bottle;
- :mod:`.ros2_io`: the bridge inside an rclpy node (the ros2 backend).

ybgc writes this package beside each module it generates, as the folder
``ybgc_runtime/`` (inside the ament package for ``--package``), or inlines it
into the module with ``--single-file``. A module refuses to start with a
runtime of another :data:`VERSION` (docs/runtime.md, "The runtime library").
"""

#: the version of this runtime; a module checks it before it uses anything
VERSION = "0.2.0"
