"""The checked program: ybgc's intermediate representation.

Frozen dataclasses, independent of the surface syntax (legacy or named form)
and of every backend. A config is one bridge of a kind: a stream (a
:class:`Program`, :mod:`.streams`) or commands (a :class:`Commands`,
:mod:`.commands`), each class naming its ``kind``
(:data:`BRIDGE_KINDS`); a module is one bridge, or a robot's bridges
composed. The checker (``check.py``) builds the program;
backends read nothing else. Every value here is already validated: names are
legal YARP port / ROS topic names, literals carry their element type, widths
and slices are resolved. ``to_json``/``from_json`` give the form printed by
``ybgc ir``.

Every element a backend may refuse or report on (an input, a mux, a
converter, a field, a message, the output and its type) carries ``span``:
where the config writes it, or, for what the config leaves to its
defaults, the nearest line that decides it (``passes/spans.py``). Spans
take no part in equality: two programs that build the same module are
equal wherever they were written.

The pipeline of one bridge::

    inputs (YARP ports or ROS topics) --> Mux (concatenate, in port order)
        --> converters (per element range) --> message tree --> Output

Terms used throughout:

element type
    A ROS primitive name (``float64``, ``int32``, ``string``, ``bool`` ...):
    the type of one element of a mux.
width
    Number of elements; ``None`` where it is only known at run time (legacy
    ports carry no declaration).
"""

from typing import Union

from ybg.compiler.ir.streams import *  # noqa: F401,F403
from ybg.compiler.ir.commands import *  # noqa: F401,F403
from ybg.compiler.ir.actions import *  # noqa: F401,F403
from ybg.compiler.ir.serial import *  # noqa: F401,F403

#: the kinds of bridge: kind -> the IR class of its checked program
BRIDGE_KINDS = {cls.kind: cls for cls in (Program, Commands, Actions)}  # noqa: F405
#: a checked program of any kind
Bridge = Union[Program, Commands, Actions]  # noqa: F405
