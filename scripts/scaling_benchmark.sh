#!/usr/bin/env bash
# Issue 13's scaling figures: matching and mapping time per photo on rendered aerial surveys
# of 50, 100 and 200 photos (`reconduit synthetic`: 5 x 10, 10 x 10 and 10 x 20 photos over a
# hilly terrain, 800 x 600 px, ~75 % overlap along a row and ~65 % across), each run from
# scratch by `reconduit benchmark --gt` up to the sparse stage. Prints one line per size with
# registered photos, camera accuracy, pairs matched, the stages' times, seconds per photo
# for matching and mapping, and at the end the ratio of the largest size's time per photo to
# the smallest's (issue 13 asks for at most 2).
#
#   bash scripts/scaling_benchmark.sh [BUILD_DIR] [SIZES...]   (default build/release, 50 100 200)
#
# About an hour here (2 cores) for the three sizes, most of it the 200-photo run. The rendered
# photos stay in ${RECONDUIT_SCALING_DIR:-/tmp/reconduit-scaling}/<size> and are reused by
# the next run; each benchmark's work folder is <size>.work beside them.
set -euo pipefail
cd "$(dirname "$0")/.."
build=${1:-build/release}
shift || true
sizes=("$@")
[ ${#sizes[@]} -eq 0 ] && sizes=(50 100 200)
reconduit="$build/cli/reconduit"
[ -x "$reconduit" ] || { echo "scaling_benchmark: $reconduit is not built" >&2; exit 2; }
root=${RECONDUIT_SCALING_DIR:-/tmp/reconduit-scaling}
mkdir -p "$root"

grid() {  # grid SIZE: "rows cols" of the survey
  case "$1" in
    50) echo "5 10" ;; 100) echo "10 10" ;; 200) echo "10 20" ;; 300) echo "15 20" ;;
    *) echo "scaling_benchmark: no grid for $1 photos (50, 100, 200, 300)" >&2; exit 2 ;;
  esac
}

summary=()
for n in "${sizes[@]}"; do
  read -r rows cols < <(grid "$n")
  set_dir="$root/$n"
  if [ ! -f "$set_dir/cameras_par.txt" ]; then
    rm -rf "$set_dir"
    "$reconduit" synthetic "$set_dir" --rows "$rows" --cols "$cols" >/dev/null
  fi
  work="$root/$n.work"
  rm -rf "$work"
  echo "== $n photos ($rows x $cols)"
  "$reconduit" benchmark "$set_dir/images" --gt "$set_dir/cameras_par.txt" --work "$work" \
    2>/dev/null | tee "$root/$n.txt"
  line=$(python3 - "$work/reconduit/output/report.json" "$n" <<'PY'
import json, sys
report = json.load(open(sys.argv[1]))
n = int(sys.argv[2])
stages = {s["name"]: s for s in report["stages"]}
matching, sparse = stages["matching"], stages["sparse"]
summary = sparse.get("summary", {})
print(f'{n} {matching["seconds"]:.1f} {sparse["seconds"]:.1f} '
      f'{matching["summary"]["pairs"]} {summary.get("registered", "?")} '
      f'{stages["features"]["seconds"]:.1f} {report["peak_memory_bytes"] / 2**30:.2f}')
t = summary.get("seconds", {})
if t:
    print(f'  mapping of {n} photos: registration {t["registration"]:.1f} s '
          f'({t["registration_tries"]} tries), triangulation {t["triangulation"]:.1f} s, local '
          f'adjustments {t["local_adjustment"]:.1f} s ({t["local_adjustments"]}), global '
          f'adjustments {t["global_adjustment"]:.1f} s ({t["global_adjustments"]})',
          file=sys.stderr)
PY
)
  summary+=("$line")
done

echo
echo "photos  pairs  features s  matching s  mapping s  matching s/photo  mapping s/photo  peak GiB"
for line in "${summary[@]}"; do
  read -r n m s pairs registered f peak <<<"$line"
  awk -v n="$n" -v m="$m" -v s="$s" -v p="$pairs" -v f="$f" -v g="$peak" 'BEGIN {
    printf "%6d %6d %11.1f %11.1f %10.1f %17.3f %16.3f %9.2f\n", n, p, f, m, s, m / n, s / n, g }'
done
if [ ${#summary[@]} -ge 2 ]; then
  read -r n0 m0 s0 _ <<<"${summary[0]}"
  read -r n1 m1 s1 _ <<<"${summary[-1]}"
  awk -v n0="$n0" -v m0="$m0" -v s0="$s0" -v n1="$n1" -v m1="$m1" -v s1="$s1" 'BEGIN {
    printf "time per photo, %d photos against %d: matching %.2f x, mapping %.2f x, both %.2f x\n",
      n1, n0, (m1 / n1) / (m0 / n0), (s1 / n1) / (s0 / n0), ((m1 + s1) / n1) / ((m0 + s0) / n0) }'
fi
