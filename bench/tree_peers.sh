#!/usr/bin/env bash
# Instructions a step and a forward-dynamics call here, in Pinocchio and in RBDL
# (bench_tree_peers, bench/tree_peers.cpp): each engine's work alone, N1 and N2 times after
# loading, under callgrind (deterministic, unlike CPU time on a shared machine); the
# difference over N2 - N1 is one call's, the load's instructions cancelling.
#   bench/tree_peers.sh [bench_tree_peers binary] FILE...
set -euo pipefail
REPO="$(cd "$(dirname "$0")/.." && pwd)"
bin="$REPO/.catkin_ws/devel/lib/mechanism_sim/bench_tree_peers"
if [[ $# -gt 0 && -x "$1" && "$1" != *.urdf ]]; then bin="$1"; shift; fi
[[ $# -gt 0 ]] || set -- "$REPO/../shared/robots/arms/kuka_iiwa.urdf"
n1=100 n2=300
count() {  # instructions of bench_tree_peers --only $2 --steps $3 FILE
  valgrind --tool=callgrind --callgrind-out-file=/dev/null "$bin" --only "$2" --steps "$3" "$1" 2>&1 |
    sed -n 's/.*Collected : \([0-9]*\).*/\1/p'
}
printf '| robot | instructions a step: here | Pinocchio | RBDL | a forward dynamics: here | Pinocchio | RBDL |\n'
printf '|---|---|---|---|---|---|---|\n'
for file in "$@"; do
  row="| $(basename "$file" .urdf) |"
  for what in step fd; do
    for engine in here pinocchio rbdl; do
      a=$(count "$file" "$engine:$what" $n1)
      b=$(count "$file" "$engine:$what" $n2)
      row+=" $(awk -v d=$((b - a)) -v n=$((n2 - n1)) 'BEGIN { printf "%.0f", d / n }') |"
    done
  done
  echo "$row"
done
