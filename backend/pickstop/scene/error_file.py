"""An error model on its own (``pickstop.error_model``, JSON or YAML): a scene's
``error_model`` block with its ``sigma``, for the simulated vehicle (``--error-model``) and as
the output of a fit of recorded arrivals (which adds a ``fit`` section, read and ignored here).

    format: pickstop.error_model
    version: 1
    sigma: 0.05
    error_model: {kind: gaussian, mean: [0.02, 0.0], covariance: [[4e-4, 0], [0, 1e-4]],
                  stations: [...]}
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any, Literal

import yaml
from pydantic import BaseModel, ConfigDict, Field, ValidationError

from pickstop.errors import InputError
from pickstop.scene.model import ErrorModel, Scene
from pickstop.scene.positioning import Positioning, of_model

FORMAT = "pickstop.error_model"
MAX_BYTES = 4_000_000


class ErrorModelFile(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)

    format: Literal["pickstop.error_model"] = "pickstop.error_model"
    version: Literal[1] = 1
    sigma: Annotated[float, Field(ge=0, le=1.0)] | None = None  # [m]; None: the scene's
    error_model: ErrorModel
    fit: dict[str, Any] | None = None  # what a fit found (intervals, arrivals): not read

    def positioning(self, scene: Scene | None = None, sigma: float | None = None) -> Positioning:
        """The models, with the file's sigma, else ``sigma``, else the scene's (0 without)."""
        s = self.sigma if self.sigma is not None else sigma
        if s is None:
            s = scene.sigma if scene is not None else 0.0
        return of_model(self.error_model, s)


def parse_error_file(doc: Any, source: str = "error model") -> ErrorModelFile:
    try:
        return ErrorModelFile.model_validate(doc)
    except ValidationError as e:
        err = e.errors()[0]
        loc = ".".join(str(p) for p in err["loc"]) or "(root)"
        raise InputError(f"{source}: {loc}: {err['msg']}", field=loc) from None


def load_error_file(path: str | Path) -> ErrorModelFile:
    p = Path(path)
    if not p.is_file():
        raise InputError(f"error model {path}: no such file", field="error_model")
    if p.stat().st_size > MAX_BYTES:
        raise InputError(f"error model {path}: larger than {MAX_BYTES} bytes",
                         field="error_model")  # fmt: skip
    try:
        doc = yaml.safe_load(p.read_text())
    except (yaml.YAMLError, UnicodeDecodeError) as e:
        raise InputError(f"error model {path}: not YAML ({e})", field="error_model") from None
    return parse_error_file(doc, f"error model {path}")
