#!/usr/bin/env bash
# What transmissions and rotors cost a step (issue 37's bound: at most 1.2 times the arm
# without). The zoo arm (test/zoo/arm7.urdf) released from a pose that swings it, and the
# same arm with a SimpleTransmission of reduction 100 and an actuator with a rotor on every
# joint (written to a temporary file), each run 2 s under simulate at 1 ms in each
# formulation; instructions counted by callgrind (deterministic, unlike CPU time on a
# shared machine), those of a 0 s run (load, assembly) taken away, over 2000 steps.
#   bench/actuator_cost.sh [simulate binary]
set -euo pipefail
REPO="$(cd "$(dirname "$0")/.." && pwd)"
bin="${1:-$REPO/.catkin_ws/devel/lib/mechanism_sim/simulate}"
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
plain="$REPO/test/zoo/arm7.urdf"
geared="$tmp/arm7_geared.urdf"
/usr/bin/python3 - "$plain" "$geared" <<'PY'
import sys
text = open(sys.argv[1]).read()
extra = []
for k in range(1, 8):
    extra.append(f'''  <transmission name="t{k}"><type>transmission_interface/SimpleTransmission</type>
    <joint name="joint{k}"><hardwareInterface>hardware_interface/EffortJointInterface</hardwareInterface></joint>
    <actuator name="m{k}"><mechanicalReduction>100</mechanicalReduction></actuator></transmission>
  <mechanism_sim:actuator name="m{k}" rotor_inertia="3.3e-5" rated_torque="1" peak_torque="4"/>''')
i = text.rindex("</robot>")
open(sys.argv[2], "w").write(text[:i] + "\n".join(extra) + "\n" + text[i:])
PY
pose=(--set joint2=0.8 --set joint4=-0.6 --set joint6=0.5)
count() {  # instructions of simulate FILE --duration D [args]
  valgrind --tool=callgrind --callgrind-out-file=/dev/null "$bin" "$1" --duration "$2" --quiet --csv /dev/null "${@:3}" 2>&1 |
    sed -n 's/.*Collected : \([0-9]*\).*/\1/p'
}
printf '| formulation | arm7 (instructions a step) | with 7 transmissions and rotors | ratio |\n|---|---|---|---|\n'
for formulation in joint absolute; do
  a0=$(count "$plain" 0 "${pose[@]}" --formulation "$formulation")
  a2=$(count "$plain" 2 "${pose[@]}" --formulation "$formulation")
  g0=$(count "$geared" 0 "${pose[@]}" --formulation "$formulation")
  g2=$(count "$geared" 2 "${pose[@]}" --formulation "$formulation")
  awk -v f="$formulation" -v a=$((a2 - a0)) -v g=$((g2 - g0)) \
    'BEGIN { printf "| %s | %.0f | %.0f | %.3f |\n", f, a / 2000, g / 2000, g / a }'
done
