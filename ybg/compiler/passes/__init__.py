"""The passes of the checker (stage 3), one concern a module, each a
function ``run(ctx)`` over one shared :class:`~ybg.compiler.passes.context.Context`.
``ybg/compiler/check.py`` runs them in order::

    sections    sections and their keys
    dialect     module name, ROS version and distro, message definitions
    inputs      muxes, their inputs and input declarations
    converters  the converters of each mux
    output      the output, its message type and QoS
    message     the [message] entries by field path
    typed       the message tree of a known message type
    bottles     the untyped Bottle tree (YARP output, unknown type)
    images      a YARP port of camera images; the CameraInfo beside a ROS 2 image
    cuts        what the message reads of an undeclared port it cuts (W511)
    program     unused muxes, .msg problems, timing and policy -> Program
    spans       where each element of the Program came from

A config of commands ([service] sections, docs/services.md) runs
``sections``, ``dialect`` and then::

    services    each command, between a YARP RPC port and a ROS 2 service -> Commands

and a config of actions ([action] sections, docs/actions.md)::

    actions     each ROS 2 action, carried out on the robot's ports -> Actions
"""
