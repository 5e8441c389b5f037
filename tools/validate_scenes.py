#!/usr/bin/env python3
"""Validates scene files against docs/scene.schema.json (JSON Schema draft-07).

Usage: tools/validate_scenes.py [SCENE.json ...]   (default: every scenes/**/*.json outside scenes/vox/)
Prints one line per invalid file (file: JSON path: message) and exits 1 if any is invalid.
CTest runs it as Schema.BundledScenesValidate (tests/CMakeLists.txt).
"""
import json
import pathlib
import sys

import jsonschema

root = pathlib.Path(__file__).resolve().parent.parent
schema = json.loads((root / "docs" / "scene.schema.json").read_text())
jsonschema.Draft7Validator.check_schema(schema)
validator = jsonschema.Draft7Validator(schema)
# The schema must reject what the loader rejects, or passing below would prove nothing.
for bad_doc in ({"models": [{"name": "b", "generator": "box"}], "modles": []},
                {"models": [{"name": "b", "generator": "box", "radius": 3}]},
                {"models": [{"name": "b", "vox": "x.vox"}], "camera": {"fov_y": 179}}):
    if validator.is_valid(bad_doc):
        sys.exit(f"the schema accepts an invalid scene: {json.dumps(bad_doc)}")

files = [pathlib.Path(a) for a in sys.argv[1:]] or sorted(
    p for p in (root / "scenes").rglob("*.json") if "vox" not in p.relative_to(root / "scenes").parts)
bad = 0
for f in files:
    errors = list(validator.iter_errors(json.loads(f.read_text())))
    for e in errors:
        path = "".join(f"[{p}]" if isinstance(p, int) else f".{p}" for p in e.absolute_path)
        print(f"{f}: {path.lstrip('.') or '(top level)'}: {e.message}")
    bad += bool(errors)
print(f"{len(files) - bad} of {len(files)} scene files valid")
sys.exit(1 if bad else 0)
