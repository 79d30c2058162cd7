#!/usr/bin/env bash
# The layout rules of docs (README "What is in the box", issue 9), checked on the source tree:
#   - the programs' folders do not include each other: server/ nothing of worker/ or cli/,
#     worker/ nothing of server/ or cli/, cli/ nothing of server/; store/ and core/ nothing of
#     the programs; core/ nothing of store/; store/ nothing of core/ beyond util and the
#     header-only core/image/photo_metadata.h;
#   - no function outside the tests is longer than 120 lines (scripts/long_functions.py);
#   - with a build folder given: reconduit-server does not link Ceres (the server stays light).
# Usage: scripts/check_layout.sh [BUILD_DIR]; exits 1 naming what breaks a rule.
set -euo pipefail
cd "$(dirname "$0")/.."
status=0

forbid() {  # forbid FOLDER PATTERN: no file under FOLDER includes a header matching PATTERN
  local hits
  hits=$(grep -rnE "^#include \"($2)/" "$1" --include='*.h' --include='*.cc' || true)
  if [ -n "$hits" ]; then
    echo "layout: $1/ must not include $2/:"; echo "$hits"; status=1
  fi
}
forbid server 'worker|cli'
forbid worker 'server|cli'
forbid cli 'server'
forbid store 'server|worker|cli|core/(pipeline|sfm|feature|io)'
# Of core/image, the store includes only the header-only photo_metadata.h (no library).
hits=$(grep -rnE '^#include "core/image/' store --include='*.h' --include='*.cc' |
  grep -v '"core/image/photo_metadata.h"' || true)
if [ -n "$hits" ]; then
  echo "layout: store/ must not include core/image/ beyond photo_metadata.h:"; echo "$hits"; status=1
fi
forbid core 'server|worker|cli|store'

python3 scripts/long_functions.py --max 120 || status=1

if [ $# -ge 1 ]; then
  server="$1/server/reconduit-server"
  if [ ! -x "$server" ]; then
    echo "layout: $server not built"; status=1
  elif ldd "$server" | grep -q libceres; then
    echo "layout: reconduit-server links Ceres:"; ldd "$server" | grep libceres; status=1
  else
    echo "layout: reconduit-server does not link Ceres"
  fi
fi
[ $status -eq 0 ] && echo "layout: all rules hold"
exit $status
