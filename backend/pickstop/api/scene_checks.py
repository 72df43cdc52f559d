"""What a request's scenes and options must pass before anything plans them.

Checks run in order of cost: the size limits on the raw document, the mesh files (only from
the data folder's ``meshes/``, their triangles counted), the scene model and its geometry,
then the robot (a preset or registered). Errors name the request's fields.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from pickstop.api import limits as lim
from pickstop.api.body import type_errors
from pickstop.api.problems import Problem
from pickstop.api.registry import RobotRegistry
from pickstop.errors import InputError, RobotConfigError
from pickstop.scene.checks import CheckedScenes
from pickstop.scene.load import parse_scene
from pickstop.scene.mesh_file import MeshFileError, MeshFiles, claimed_triangles
from pickstop.scene.model import Scene, SceneError, resolve_mesh_paths
from pickstop.sequence.plan_model import PlanOptions
from pickstop.store.records import ServiceStore


class SceneChecks:
    """Parses and checks the scenes and options of requests against the service's limits."""

    def __init__(
        self, limits: lim.Limits, data_dir: Path, store: ServiceStore, robots: RobotRegistry
    ) -> None:
        self.limits = limits
        self.meshes = Path(data_dir) / "meshes"
        self.store = store
        self.robots = robots
        self.checked = CheckedScenes()  # the geometry checks of the last layouts
        self.mesh_files = MeshFiles()  # what each mesh file was found to be

    def parse(self, doc: Any, loc: str = "") -> Scene:
        """A scene from a request, every check passed; ``loc`` prefixes the fields named in
        errors (``scenes.2.scene.``)."""
        problems = lim.scene_problems(doc, self.limits, loc)
        if problems:
            raise SceneError(problems)
        # The model's own checks, strict as JSON, before anything walks the document.
        strict = type_errors(Scene, doc, loc) if isinstance(doc, dict) else []
        if strict:
            raise SceneError(strict)
        meshes = self.meshes
        try:
            resolved = resolve_mesh_paths(doc, meshes, [meshes])
        except SceneError as e:
            raise SceneError([(loc + f, m) for f, m in e.problems]) from None
        self._check_meshes(resolved, loc)
        try:
            scene = parse_scene(resolved, "scene", self.checked)
        except SceneError as e:
            raise SceneError([(loc + f, m) for f, m in e.problems]) from None
        if scene.robot.config is not None:
            raise SceneError([(f"{loc}robot.config", "file paths are not accepted over the API; "
                               "register the robot (POST /api/v1/robots) and name it in "
                               "robot.preset")])  # fmt: skip
        try:
            self.robots.config(scene.robot.ref)  # an unknown robot is refused now, not later
        except RobotConfigError as e:
            raise SceneError([(f"{loc}robot.preset", e.message)]) from None
        except InputError as e:
            raise SceneError([(f"{loc}{e.field or 'robot.preset'}", e.message)]) from None
        return scene

    def _check_meshes(self, resolved: Any, loc: str) -> None:
        """Every mesh file of a scene checked (:func:`pickstop.scene.mesh_file.check_mesh`),
        and all their triangles together within the limit."""
        limit, triangles = self.limits.max_mesh_triangles, 0
        for where, geom in lim.mesh_geometries(resolved):
            path, field = geom.get("path"), f"{loc}{where}.path"
            if not (isinstance(path, str) and Path(path).is_file()):
                continue  # the model names it
            claimed = claimed_triangles(Path(path))
            if claimed is None or triangles + claimed <= limit:
                scale = geom.get("scale", 1.0)
                scale = scale if isinstance(scale, int | float) and scale > 0 else 1.0
                try:
                    claimed = self.mesh_files.check(Path(path), limit, scale).triangles
                except MeshFileError as e:
                    raise SceneError([(field, f"mesh {Path(path).name!r}: {e.message}")]) from None
            triangles += claimed
            if triangles > limit:
                raise SceneError([(field, f"the scene's meshes hold {triangles} triangles up to "
                                   f"this one, over the limit of {limit}")])  # fmt: skip

    def check_options(self, options: PlanOptions, loc: str = "options.") -> None:
        if options.samples > self.limits.max_mc_samples:
            raise InputError(
                f"{loc}samples: {options.samples} Monte Carlo samples per stop exceed the limit "
                f"of {self.limits.max_mc_samples}",
                field=f"{loc}samples",
            )

    def scene_doc(self, scene_id: str | None, doc: Any, loc: str = "") -> tuple[Any, int | None]:
        """The document of a stored scene (and its revision), or the inline ``doc``."""
        if scene_id is None:
            return doc, None
        row = self.store.scene(scene_id)
        if row is None:
            raise InputError(f"scene {scene_id} does not exist", field=f"{loc}scene_id")
        return json.loads(row["doc"]), row["revision"]

    def stored_scene(self, scene_id: str) -> Scene:
        row = self.store.scene(scene_id)
        if row is None:
            raise Problem(404, "Not found", f"no scene {scene_id!r}", field="scene_id")
        return self.parse(json.loads(row["doc"]))

    def prepare(self, item: Any, loc: str = "") -> tuple[Any, int | None, Scene]:
        """A plan request's scene (stored or inline) checked as a synchronous plan checks
        it: (document, revision or None, scene)."""
        doc, revision = self.scene_doc(item.scene_id, item.scene, loc)
        scene = self.parse(doc, f"{loc}scene." if item.scene is not None else loc)
        options = getattr(item, "options", None)
        if options is not None:
            self.check_options(options)
        return doc, revision, scene

    def precheck(self, doc: Any) -> None:
        """The size limits of a plan or batch request's raw inline scenes, before the request
        model copies and validates them."""
        if not isinstance(doc, dict):
            return
        problems = lim.scene_problems(doc.get("scene"), self.limits, "scene.")
        scenes = doc.get("scenes")
        for i, item in enumerate(scenes if isinstance(scenes, list) else []):
            if isinstance(item, dict):
                problems += lim.scene_problems(item.get("scene"), self.limits, f"scenes.{i}.scene.")
        if problems:
            raise SceneError(problems)

    def check_batch_size(self, doc: Any) -> None:
        scenes = doc.get("scenes") if isinstance(doc, dict) else None
        if isinstance(scenes, list) and len(scenes) > self.limits.max_batch:
            raise Problem(413, "Request too large", f"{len(scenes)} scenes exceed the batch "
                          f"limit of {self.limits.max_batch}", kind="too-large",
                          field="scenes")  # fmt: skip
