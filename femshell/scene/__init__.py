"""Scenes: a TOML file -> the parts that scene needs and nothing else -> a run directory.

* :mod:`femshell.scene.config`: one dataclass per section (keys, ranges, defaults), the validated :class:`Scene`;
* :mod:`.schema`: validation with one-line errors; :mod:`.text`: TOML reading and writing, ``--set``;
* :mod:`.build`: the mesh, the shell, the time loop, ``--dry-run`` plans;
* :mod:`.runner`: ``femshell run``: the run's contract, ``--resume`` checks, :func:`run_scene`;
  :mod:`.rundir` (the run directory and its lock), :mod:`.progress`, :mod:`.frames` (fields and
  pictures), :mod:`.base_runner` (the loop shared by the solver kinds) and one runner per kind:
  :mod:`.time_runner`, :mod:`.static_runner`, :mod:`.continuation_runner`.

Example
-------
>>> from femshell.scene import load_scene, list_scenes
>>> "default" in list_scenes()
True
>>> sc = load_scene("clamped-plate-buckling", ["mesh.edge_length=0.25"])
>>> sc.kind, sc.growth.law
('continuation', 'uniform')
"""

from .build import embedded_scene_path, list_scenes, load_scene, make_mesh, plan
from .runner import RunDirError, run_scene
from .schema import Scene, SceneError

__all__ = ["run_scene", "list_scenes", "load_scene", "make_mesh", "plan", "embedded_scene_path", "Scene",
           "SceneError", "RunDirError"]
