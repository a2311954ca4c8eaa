#!/usr/bin/env bash
# The README's benchmark figures come from the committed report, not from hand copies: every
# block of README.md between
#   <!-- report: SECTION TITLE -->  and  <!-- end report -->
# is replaced by that section of bench/results/REPORT.md (its command line and its tables, up
# to its first plot heading), under a line that names the report's commit and command.
# scripts/bench-report.sh runs it after writing the default report; the test suite runs
# --check, which fails when the README and the committed report disagree.
#
# usage: scripts/readme-figures.sh [--check]   env: README, REPORT (defaults in this tree)
set -euo pipefail
here="$(cd "$(dirname "$0")/.." && pwd)"
README="${README:-$here/README.md}"
REPORT="${REPORT:-$here/bench/results/REPORT.md}"
check=0
case "${1:-}" in
  --check) check=1 ;;
  "") ;;
  *) echo "usage: scripts/readme-figures.sh [--check]" >&2; exit 2 ;;
esac
[ -f "$README" ] || { echo "readme-figures: $README not found" >&2; exit 1; }
[ -f "$REPORT" ] || { echo "readme-figures: $REPORT not found (make bench-quick)" >&2; exit 1; }
# --check writes nothing beside the README (a read-only checkout); an update writes a
# temporary file beside it and renames it over it.
if [ "$check" = 1 ]; then tmp="$(mktemp "${TMPDIR:-/tmp}/readme-figures.XXXXXX")"; else tmp="$README.tmp-$$"; fi
trap 'rm -f "$tmp"' EXIT
awk -v report="$REPORT" '
  function section(title,   line, on, out, n, i, lines) {
    on = 0; n = 0
    while ((getline line < report) > 0) {
      if (on && (line ~ /^## / || line ~ /^### /)) break
      if (on) lines[++n] = line
      if (line == "## " title) on = 1
    }
    close(report)
    if (!on) { printf "readme-figures: no section \"%s\" in %s\n", title, report > "/dev/stderr"; failed = 1; return "" }
    while (n > 0 && lines[n] == "") n--
    i = 1
    while (i <= n && lines[i] == "") i++
    out = ""
    for (; i <= n; i++) out = out lines[i] "\n"
    return out
  }
  BEGIN {
    while ((getline line < report) > 0) if (line ~ /^- commit: /) { provenance = substr(line, 3); break }
    close(report)
  }
  /^<!-- report: .* -->$/ {
    title = $0; sub(/^<!-- report: /, "", title); sub(/ -->$/, "", title)
    print
    printf "From `bench/results/REPORT.md` (%s), section \"%s\":\n\n", provenance, title
    printf "%s", section(title)
    skipping = 1; next
  }
  /^<!-- end report -->$/ { if (!skipping) { print "readme-figures: an end marker without its start" > "/dev/stderr"; failed = 1 } skipping = 0; print; next }
  !skipping { print }
  END { if (skipping) { print "readme-figures: a report block without its end marker" > "/dev/stderr"; failed = 1 } exit failed }
' "$README" >"$tmp" || { echo "readme-figures: $README not updated" >&2; exit 1; }
if [ "$check" = 1 ]; then
  if ! cmp -s "$tmp" "$README"; then
    echo "readme-figures: README.md's report blocks differ from bench/results/REPORT.md (run scripts/readme-figures.sh):" >&2
    diff "$README" "$tmp" | head -n 20 >&2 || true
    exit 1
  fi
  echo "readme-figures: README.md's report blocks match bench/results/REPORT.md"
  exit 0
fi
mv "$tmp" "$README"
trap - EXIT
echo "readme-figures: README.md's report blocks taken from $(basename "$REPORT")"
