#!/usr/bin/env bash
# CPU time a step of the robot zoo (test/zoo) and of the real robot files in
# ../shared/robots (when present), RK4 at 1 ms: `simulate --duration 5 --quiet`, the median
# of 3 runs of this process's user CPU time over 5000 steps (load and assembly included,
# a few ms). Figures in bench/RESULTS.md and doc/robots.md.
#   bench/robots.sh [simulate binary]
# FORMULATION=absolute|joint|auto (environment) passes --formulation (default: the
# simulator's own, absolute).
set -euo pipefail
REPO="$(cd "$(dirname "$0")/.." && pwd)"
bin="${1:-$REPO/.catkin_ws/devel/lib/mechanism_sim/simulate}"
files=("$REPO"/test/zoo/*.urdf)
for f in "$REPO"/../shared/robots/arms/*.urdf "$REPO"/../shared/robots/legged/*.urdf; do [ -f "$f" ] && files+=("$f"); done
extra=()
[ -n "${FORMULATION:-}" ] && extra=(--formulation "$FORMULATION")
tmp=$(mktemp)
trap 'rm -f "$tmp"' EXIT
printf '| robot | equations | µs a step (CPU) |\n|---|---|---|\n'
for f in "${files[@]}"; do
  eq=$("$bin" "$f" --duration 0 --csv /dev/null 2>&1 | grep -o '[0-9]* constraint equations\|of [0-9]* constraint' | grep -o '[0-9]*' | tail -1)
  if ! err=$("$bin" "$f" --duration 5 --quiet "${extra[@]}" 2>&1 >/dev/null); then
    printf '| %s | %s | fails: %s |\n' "${f#"$REPO"/}" "$eq" "$(echo "$err" | tail -1 | cut -c1-160)"
    continue
  fi
  runs=()
  for _ in 1 2 3; do
    /usr/bin/time -o "$tmp" -f '%U' "$bin" "$f" --duration 5 --quiet "${extra[@]}" >/dev/null 2>&1
    runs+=("$(tail -1 "$tmp")")
  done
  med=$(printf '%s\n' "${runs[@]}" | sort -g | sed -n 2p)
  printf '| %s | %s | %s |\n' "${f#"$REPO"/}" "$eq" "$(awk -v s="$med" 'BEGIN { printf "%.0f", s * 1e6 / 5000 }')"
done
