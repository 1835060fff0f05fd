#!/usr/bin/env bash
# The paper profile (`reproduce --profile paper`) across sessions and machines.
#
# The profile needs ≈ 6 h on a 2-core machine, longer than a working session, and its 12
# parts must come from one commit to merge. So it runs from a git worktree frozen at COMMIT,
# one part at a time at nice 10 with `--resume`, and its finished measures (checkpoints and
# run directories: a few hundred KB, never the builds or scenes) are saved into the
# repository under paper/progress/COMMIT/ (by the driver every 10 minutes, and by `save`),
# from where a later machine restores them and goes on at the first unfinished measure.
# When all 12 parts' `reproduce-part.json` say `"complete": true`, `merge` writes
# report-paper.md from them.
#
#   scripts/paper-profile.sh start COMMIT   # worktree + release build + restore + driver
#   scripts/paper-profile.sh save COMMIT    # copy finished measures into paper/progress/
#   scripts/paper-profile.sh status COMMIT  # parts done, measures checkpointed
#   scripts/paper-profile.sh merge COMMIT   # all parts done: report into paper/
#   scripts/paper-profile.sh stop           # stop the driver (a measure in flight is lost)
#
# PAPER_WORK (default /tmp/paper) holds the worktree, the scene cache and the logs.
set -euo pipefail

ROOT=$(cd "$(dirname "$0")/.." && pwd)
WORK=${PAPER_WORK:-/tmp/paper}
OUT=results/reproduce-paper
# Part order: MWKD on 186.85 M first (its builds dominate), then LPC on 167 M, QSplat on
# 127 M, LPC's 234 M isosurface, the rest. FILE after ':' is the cached scene that no later
# part needs, deleted once the part is done (the disk holds one or two at a time).
ORDER=(11 10 9 8:statue-186850683-1-even2-v1.sbc 6 5 7:statue-167000000-1-even2-v1.sbc
  0 2:statue-127072827-1-even2-v1.sbc 4:isosurface-deep-234000000-1-even2-v1.sbc 3 1)

die() { echo "paper-profile: $*" >&2; exit 1; }

cmd=${1:-}
[ -n "$cmd" ] || die "usage: $0 start|save|status|merge COMMIT, or $0 stop"
if [ "$cmd" = stop ]; then
  pkill -f "$WORK/drive.sh" || true
  pkill -f "$WORK/bin/splatbench reproduce" || true
  exit 0
fi
[ $# -eq 2 ] || die "usage: $0 $cmd COMMIT"
commit=$(git -C "$ROOT" rev-parse --verify "$2^{commit}" 2>/dev/null) ||
  die "'$2' is not a commit of $ROOT"
short=${commit:0:12}
saved=$ROOT/paper/progress/$short
wt=$WORK/wt
parts=$wt/$OUT/parts

# The part directories' small files: checkpoints, runs, part records; no builds.
copy_parts() { # FROM TO
  (cd "$1" && find . -path '*/builds' -prune -o -type f -size -2M -print) |
    while read -r f; do
      mkdir -p "$2/$(dirname "$f")"
      cp -p "$1/$f" "$2/$f"
    done
}

case "$cmd" in
start)
  mkdir -p "$WORK/bin" "$WORK/cache"
  if [ ! -d "$wt" ]; then
    git -C "$ROOT" worktree add --detach "$wt" "$commit"
  fi
  [ "$(git -C "$wt" rev-parse HEAD)" = "$commit" ] || die "$wt is not at $short"
  if [ ! -x "$WORK/bin/splatbench" ]; then
    (cd "$wt" && cargo build --release --bin splatbench)
    cp "$wt/target/release/splatbench" "$WORK/bin/"
  fi
  # grep -c reads all of strings' output: with `grep -q` and pipefail, strings may die of
  # SIGPIPE when grep stops early, and the check fails on the right binary.
  [ "$(strings "$WORK/bin/splatbench" | grep -c "$short")" -gt 0 ] ||
    die "$WORK/bin/splatbench is not built at $short (delete it to rebuild)"
  (cd "$wt" && "$WORK/bin/splatbench" reproduce --profile paper --publish paper --emit-jobs jobs.txt --out "$OUT")
  if [ -d "$saved/parts" ]; then
    mkdir -p "$parts"
    copy_parts "$saved/parts" "$parts"
  fi
  cat > "$WORK/drive.sh" <<EOF
#!/usr/bin/env bash
cd "$wt" || exit 1
export SPLATBENCH_CACHE="$WORK/cache"
# Every 10 minutes the finished measures go into paper/progress/ (outside /tmp, which a
# machine restart empties), so at most one measure is lost when the machine goes away.
( while sleep 600; do "$ROOT/scripts/paper-profile.sh" save "$commit" > /dev/null 2>&1; done ) &
saver=\$!
for arg in ${ORDER[*]}; do
  k=\${arg%%:*}; del=; [ "\$arg" != "\$k" ] && del=\${arg#*:}
  grep -qs '"complete": true' "$parts/part-\$(printf %03d \$k)/reproduce-part.json" && continue
  line=\$(sed -n "\$((k+1))p" jobs.txt)
  echo "\$(date -u +%FT%TZ) part \$k start" >> "$WORK/drive.log"
  nice -n 10 bash -c "\$line --resume" >> "$WORK/log-\$k.txt" 2>&1
  rc=\$?
  echo "\$(date -u +%FT%TZ) part \$k rc=\$rc" >> "$WORK/drive.log"
  # A part that failed stays pending, whatever its record says (a binary before 5b3f4ab
  # marked a part whose tables failed as complete): the next start runs it again.
  [ \$rc -ne 0 ] && sed -i 's/"complete": true/"complete": false/' "$parts/part-\$(printf %03d \$k)/reproduce-part.json"
  [ \$rc -eq 0 ] && [ -n "\$del" ] && rm -fv "$WORK/cache/\$del" >> "$WORK/drive.log"
done
"$ROOT/scripts/paper-profile.sh" save "$commit" > /dev/null 2>&1
kill \$saver
echo "\$(date -u +%FT%TZ) driver end" >> "$WORK/drive.log"
EOF
  chmod +x "$WORK/drive.sh"
  nohup "$WORK/drive.sh" > /dev/null 2>&1 &
  echo "driver started (log: $WORK/drive.log)"
  ;;
save)
  [ -d "$parts" ] || die "no parts under $parts"
  mkdir -p "$saved/parts"
  copy_parts "$parts" "$saved/parts"
  echo "saved into ${saved#"$ROOT"/}: $(du -sh "$saved" | cut -f1)"
  ;;
status)
  for d in "$parts"/part-* "$saved"/parts/part-*; do
    [ -d "$d" ] || continue
    n=$({ find "$d/measures" -name '*.json' 2>/dev/null || true; } | wc -l)
    done=no; grep -qs '"complete": true' "$d/reproduce-part.json" && done=yes
    echo "${d#"$ROOT"/}: $n measures checkpointed, part done: $done"
  done
  ;;
merge)
  for k in $(seq 0 11); do
    grep -qs '"complete": true' "$parts/part-$(printf %03d "$k")/reproduce-part.json" ||
      die "part $k is not done"
  done
  (cd "$wt" && "$WORK/bin/splatbench" merge "$parts"/part-* --out "$OUT")
  cp "$wt/paper/report-paper.md" "$wt/paper/results-paper.json" "$ROOT/paper/"
  rm -rf "$ROOT/paper/figures-paper"
  cp -r "$wt/paper/figures-paper" "$ROOT/paper/"
  echo "paper/report-paper.md written"
  ;;
*) die "unknown command '$cmd'" ;;
esac
