#!/usr/bin/env bash
# The browser way: the API and the 3D planner for one scene file, on 127.0.0.1.
#   examples/browser.sh [SCENE.json]     then open the printed planner URL
set -euo pipefail
scene="${1:-$(dirname "$0")/scenes/five_trays.json}"
pickstop reach build --quiet > /dev/null          # the default database, once (a no-op later)
export PICKSTOP_API_KEYS="[]"                     # the planner brings its own key for saving
exec pickstop serve --scene-file "$scene"
