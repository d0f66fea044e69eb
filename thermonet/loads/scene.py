"""``[loads.<name>]`` tables of a scene as :class:`~thermonet.loads.Drive` / :class:`~thermonet.loads.Force`
objects, checked against the net with errors at the key's file:line."""

from __future__ import annotations

import re

from ..errors import InputError
from .arrays import resolve
from .spec import Drive, Force

_KEY = re.compile(r"^(loads\.[A-Za-z0-9_\-]+(?:\.[A-Za-z_]+)*)(?:\[\d\])?(?:\.table)?: ")


def scene_loads(scene, net) -> dict | None:
    """name -> load of the scene's ``[loads.*]`` tables (None when there are none)."""
    tables = scene.data.get("loads") or {}
    if not tables:
        return None
    loads = {}
    for name, t in tables.items():
        group = t["group"]
        if t["type"] == "drive":
            for key in ("force", "total"):
                if t.get(key) not in (None, False):
                    raise scene.error(("loads", name, key), f"{key} belongs to a force; this load is a drive")
            loads[name] = Drive(group, displacement=t.get("displacement"), direction=t.get("direction"),
                                velocity=t.get("velocity"), free=t["free"], name=name)
        else:
            for key in ("displacement", "velocity", "free"):
                if t.get(key) not in (None, False):
                    raise scene.error(("loads", name, key), f"{key} belongs to a drive; this load is a force")
            loads[name] = Force(group, force=t.get("force"), direction=t.get("direction"), total=t["total"],
                                name=name)
    try:
        resolve(loads, net)
    except InputError as exc:
        message = str(exc)
        match = _KEY.match(message)
        if match:
            raise scene.error(tuple(match.group(1).split(".")), message[match.end():]) from None
        raise scene.error(("loads",), message) from None
    return loads
