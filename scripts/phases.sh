# Sourced by scripts/test.sh and scripts/sanitize.sh: `phase NAME COMMAND...` runs COMMAND and
# records how long it took; `phases_summary` prints every phase recorded so far (a script run by
# another one adds to its caller's list: GSD_PHASES_FILE) and the total. CI's log ends with it.
if [ -z "${GSD_PHASES_FILE:-}" ]; then
  GSD_PHASES_FILE=$(mktemp /tmp/gsd-phases.XXXXXX)
  GSD_PHASES_START=$SECONDS
  export GSD_PHASES_FILE GSD_PHASES_START
  gsd_phases_owner=1
fi

phase() {
  local name=$1 start=$SECONDS rc=0
  shift
  echo "=== $name"
  "$@" || rc=$?
  local took=$((SECONDS - start)) state=""
  [ "$rc" -eq 0 ] || state="  (failed, exit $rc)"
  printf '  %-44s %6d s%s\n' "$name" "$took" "$state" >> "$GSD_PHASES_FILE"
  echo "=== $name: $took s${state}"
  return "$rc"
}

phases_summary() {
  [ "${gsd_phases_owner:-0}" = 1 ] || return 0
  echo "--- phases"
  cat "$GSD_PHASES_FILE"
  printf '  %-44s %6d s\n' "total" "$((SECONDS - GSD_PHASES_START))"
  rm -f "$GSD_PHASES_FILE"
}
