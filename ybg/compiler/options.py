"""What the command line adds to a config, passed to every stage of the
front end (the pipeline, the checker, the legacy conversion)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping


@dataclass(frozen=True)
class Options:
    """What the command line adds to a config: ``distro`` overrides
    ``[module] distro``; ``msg_path`` directories of user ``.msg`` files;
    ``environ`` the environment searched for more (``YBG_MSG_PATH``,
    ``ROS_PACKAGE_PATH``, ``AMENT_PREFIX_PATH``; None: the process's own);
    ``yarp`` the YARP version the module is for ("3.12", "4.0.0"; None: any)."""

    distro: str | None = None
    msg_path: tuple[str, ...] = ()
    environ: Mapping[str, str] | None = None
    yarp: str | None = None
