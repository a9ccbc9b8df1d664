"""The lowering library: what every backend needs to turn a checked
:class:`~ybg.compiler.ir.Program` into the view-model its templates print,
and that no backend owns.

- :mod:`.errors`: :class:`LoweringError` (a program a backend cannot build,
  with the span of the part it refuses) and :class:`Line`, one line of
  generated code;
- :mod:`.tree`: the message tree: nesting of dotted fields, literal values
  and defaults, sizes and slice ranges, the message types a program uses;
- :mod:`.rosnames`: ROS naming: ``pkg/Name`` split and checked, ROS 2 type
  names, package, node and header names, the node's parameters;
- :mod:`.wire`: the Bottle layout (the tag of each element type on a YARP
  port and on a ROS 1 topic through YARP);
- :mod:`.python`: Python source for the runtime library's specs and the
  Bottle builder, shared by the backends that write Python;
- :mod:`.package`: the ROS 2 package and launch file around a module, and
  a composed module's parameter file;
- :mod:`.compose`: what composed modules share, and the file name of a
  program's config (in every module's texts that name it);
- :mod:`.ros2_events`: what both runtimes say and count of the incompatible
  peers of a module's ROS 2 publishers and subscriptions;
- :mod:`.templates`: the Jinja environment (templates only print) and its
  filters;
- :mod:`.yarpmanager`: the yarpmanager application of a module.

How the runtime library reaches a module is ``ybg.backends.runtime``, which
every backend uses too. A backend (``ybg.backends.<name>``) imports this
library and the IR, never another backend; this library imports the IR and
nothing of the backends (tests/test_layers.py checks both).
"""
