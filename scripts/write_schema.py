"""Write the published JSON Schema of the scene format to docs/scene.schema.json."""

import json
from pathlib import Path

from pickstop.scene.model import scene_json_schema

out = Path(__file__).parents[1] / "docs" / "scene.schema.json"
out.write_text(json.dumps(scene_json_schema(), indent=2) + "\n")
print(out)
