#!/usr/bin/env bash
# examples/render_scene draws what `voxtier render` draws, byte for byte, on scenes/default.json:
# the still (the scene file's static camera: the library applies the CLI's camera rule) and a
# frame of the camera path. Usage: example_test.sh VOXTIER RENDER_SCENE SCENES_DIR (the build
# tree's, or an installed tree's: tests/install_consumer.sh).
set -euo pipefail
cli="$1"
example="$2"
scene="$3/default.json"
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
"$cli" render "$scene" -o "$work/cli.png" >/dev/null
"$example" "$scene" "$work/example.png"
cmp "$work/cli.png" "$work/example.png"
"$cli" render "$scene" --frame 40 -o "$work/cli_40.png" >/dev/null
"$example" "$scene" "$work/example_40.png" 40
cmp "$work/cli_40.png" "$work/example_40.png"
# The still is not the path's first frame (default.json positions its camera at the path's last
# key), so the comparison above sees whether the camera rule was applied.
"$cli" render "$scene" --frame 0 -o "$work/cli_0.png" >/dev/null
if cmp -s "$work/cli.png" "$work/cli_0.png"; then
    echo "example_test: the still equals path frame 0: the scene no longer tells the rule apart" >&2
    exit 1
fi
echo "example_test: render_scene wrote the CLI's images, byte for byte (still and frame 40)"
