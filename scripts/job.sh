#!/usr/bin/env bash
# Set everything up, then run the main job on the bundled default model.
# Extra arguments go to `python3 -m tsplcam job`; the program, CL data, processing list,
# report.json and report.html (with report_files/) land in build/job; the last line says
# where the report is.
set -euo pipefail
REPO="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
bash "$REPO/scripts/install.sh"
cd "$REPO"
exec /usr/bin/python3 -m tsplcam job --out "$REPO/build/job" "$@"
