"""`motion-env studio`: type a caption, click waypoints, watch the characters stream in 3-D in a
browser.

What is where:

- :mod:`.session`: :class:`StudioSession`, the characters, their routes, goals and obstacles, one
  frame per tick (no web page; numpy and the generator only);
- :mod:`.route_progress`: one character's waypoints and its progress along them;
- :mod:`.agent`: the A* agent (:mod:`policies.astar`) that walks a character to a goal;
- :mod:`.geometry`: clicks onto the floor, the figure as bone segments, drawn paths to waypoints;
- :mod:`.keep`: a clip as .npz, BVH or robot file bytes;
- :mod:`.robot_view`: the selected character retargeted onto a robot live, and its meshes;
- :mod:`.server`, :mod:`.view`, :mod:`.panel`: the page, built on viser (the optional ``studio``
  extra, ``pip install -c constraints.txt -e ".[studio]"``), imported only by the command that serves it.
"""

from motion_env.studio.session import StudioSession
from motion_env.studio.state import Snapshot, Stats

__all__ = ["Snapshot", "Stats", "StudioSession"]
