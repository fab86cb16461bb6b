#!/usr/bin/env bash
# Times the whole `brdf-rig reconstruct` a user runs, as separate processes, on every
# several-material scene that `brdf-rig bench materials --scratch DIR` wrote: with
# `--materials auto` and with one material (the default), in turn, REPEATS times each; keeps the
# least of each and prints one line per scene, then the ratios' summary (issue #17's time bar:
# at most 2x the one-material reconstruction of the same images).
#
# Usage: scripts/time_commands.sh BINARY SCRATCH_DIR [REPEATS] [EXTRA reconstruct ARGS...]
#   BINARY: e.g. target/release/brdf-rig; SCRATCH_DIR: the bench's --scratch folder.
# The scene folders are named MESH-MAT1+MAT2[+MAT3]-RIG-SEED; each is reconstructed with the
# bench's basis (--basis-components 64 --basis-stride 1,2,2, its materials excluded).
set -euo pipefail
bin=$1
scratch=$2
repeats=${3:-2}
shift $(( $# < 3 ? $# : 3 ))
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
lines=()
for d in "$scratch"/*/; do
  n=$(basename "$d")
  mats=$(echo "$n" | sed -E 's/^[^-]+-//; s/-(spread|one[0-9]+)-[0-9]+$//')
  case $mats in *+*) ;; *) continue ;; esac
  best_auto=""; best_one=""
  for _ in $(seq "$repeats"); do
    for m in auto one; do
      /usr/bin/time -o "$out/t" -f "%e" "$bin" reconstruct "$d/job.toml" --materials "$m" \
        --basis-components 64 --basis-stride 1,2,2 --exclude "$(echo "$mats" | tr '+' ',')" \
        "$@" --out "$out/$m" > /dev/null 2> "$out/$m.log"
      s=$(tail -1 "$out/t")
      if [ "$m" = auto ]; then
        best_auto=$(python3 -c "print(min(float('$s'), float('${best_auto:-inf}')))")
        count=$(python3 -c "import json; print(len(json.load(open('$out/auto/materials.json'))['materials']))" 2> /dev/null || echo 1)
      else
        best_one=$(python3 -c "print(min(float('$s'), float('${best_one:-inf}')))")
      fi
      rm -rf "${out:?}/$m"
    done
  done
  line="$n $count $best_auto $best_one"
  echo "$line"
  lines+=("$line")
done
printf '%s\n' "${lines[@]}" | python3 -c '
import math, sys
rows = [l.split() for l in sys.stdin if l.strip()]
gm = lambda v: math.exp(sum(map(math.log, v)) / len(v))
r = [float(a) / float(o) for _, _, a, o in rows]
print("whole command, auto / one: gm %.3f, max %.3f, within 2x %d of %d; summed %.1f s / %.1f s = %.3f" % (
    gm(r), max(r), sum(x <= 2 for x in r), len(r),
    sum(float(x[2]) for x in rows), sum(float(x[3]) for x in rows),
    sum(float(x[2]) for x in rows) / sum(float(x[3]) for x in rows)))
for k in sorted(set(x[1] for x in rows)):
    v = [float(a) / float(o) for _, c, a, o in rows if c == k]
    print("  %s materials found: gm %.3f, max %.3f over %d" % (k, gm(v), max(v), len(v)))
'
