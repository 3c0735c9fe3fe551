#!/usr/bin/env bash
# The rerun viewer on a heave-with-buffered-compensator run, as a user sees it, headless:
# docs/rerun_heave_buffered.png. Needs Debian's xvfb and mesa-vulkan-drivers (software Vulkan, lavapipe)
# and hexsim installed (the `rerun` binary comes with rerun-sdk):
#   apt-get install -y xvfb mesa-vulkan-drivers
#   bash docs/rerun_screenshot.sh [OUT.png]
# The viewer renders the recording's own blueprint and writes the screenshot itself (--screenshot-to),
# so nothing depends on capturing the X screen.
set -euo pipefail
out="${1:-docs/rerun_heave_buffered.png}"
work="$(mktemp -d)"
trap 'kill "$xvfb" 2>/dev/null || true; rm -rf "$work"' EXIT

hexsim run heave --compensator buffered --rrd "$work/heave_buffered.rrd" --quiet
Xvfb :97 -screen 0 1600x1000x24 >/dev/null 2>&1 &
xvfb=$!
sleep 2
DISPLAY=:97 XDG_RUNTIME_DIR="$work" WGPU_BACKEND=vulkan \
    VK_ICD_FILENAMES=/usr/share/vulkan/icd.d/lvp_icd.x86_64.json \
    timeout 300 rerun "$work/heave_buffered.rrd" --port auto --window-size 1600x1000 \
    --screenshot-to "$work/shot.png" >/dev/null 2>&1
# halve the HiDPI capture (3200 x 2000) for the docs
python - "$work/shot.png" "$out" <<'PY'
import sys
from PIL import Image
Image.open(sys.argv[1]).convert("RGB").resize((1600, 1000), Image.LANCZOS).save(sys.argv[2], optimize=True)
PY
echo "wrote $out"
