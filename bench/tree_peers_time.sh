#!/usr/bin/env bash
# CPU time here against RBDL and Pinocchio, as ratios: bench_tree_peers (bench/tree_peers.cpp)
# run N times in a row on each FILE, each run measuring the three engines interleaved; the
# median over the runs of here/RBDL and here/Pinocchio, a step and a forward dynamics, with
# the range. One run's ratio moves by several per cent on a shared machine; the median of
# many runs is what bench/RESULTS.md quotes.
#   bench/tree_peers_time.sh [-n N] [bench_tree_peers binary] FILE...
set -euo pipefail
REPO="$(cd "$(dirname "$0")/.." && pwd)"
bin="$REPO/.catkin_ws/devel/lib/mechanism_sim/bench_tree_peers"
runs=101
if [[ $# -gt 1 && "$1" == "-n" ]]; then runs=$2; shift 2; fi
if [[ $# -gt 0 && -x "$1" && "$1" != *.urdf ]]; then bin="$1"; shift; fi
[[ $# -gt 0 ]] || set -- "$REPO/../shared/robots/arms/kuka_iiwa.urdf"
printf '| robot | runs | step here/RBDL: median (range) | here/Pinocchio | forward dynamics here/RBDL | here/Pinocchio | here µs a step (median) |\n'
printf '|---|---|---|---|---|---|---|\n'
for file in "$@"; do
  for ((r = 0; r < runs; ++r)); do "$bin" "$file" | tail -1; done | python3 -c '
import statistics as st, sys
rows = [[float(x) for x in l.split("|")[3:9]] for l in sys.stdin if l.startswith("|")]
step_r = [h / r for h, p, r, fh, fp, fr in rows]
step_p = [h / p for h, p, r, fh, fp, fr in rows]
fd_r = [fh / fr for h, p, r, fh, fp, fr in rows]
fd_p = [fh / fp for h, p, r, fh, fp, fr in rows]
name = sys.argv[1].rsplit("/", 1)[-1].rsplit(".", 1)[0]
print("| %s | %d | %.3f (%.2f to %.2f) | %.3f | %.3f (%.2f to %.2f) | %.3f | %.2f |" % (
    name, len(rows), st.median(step_r), min(step_r), max(step_r), st.median(step_p),
    st.median(fd_r), min(fd_r), max(fd_r), st.median(fd_p), st.median([r[0] for r in rows])))
' "$file"
done
