#!/usr/bin/env bash
# Lists the functions in src/ longer than a limit (default 80 lines: named stages, no long functions) and
# fails when there is one. Lengths from universal-ctags (first to last line of the definition).
#   scripts/function_lengths.sh [LIMIT]
set -euo pipefail
limit=${1:-80}
cd "$(dirname "$0")/.."
if ! ctags --version 2>/dev/null | grep -q "Universal Ctags"; then
  echo "function_lengths: universal-ctags is not installed (scripts/setup.sh --extra installs it)" >&2
  exit 77
fi
long=$(ctags -R --languages=C++ --kinds-C++=f --fields=+ne --extras=-F -o - src |
  awk -F'\t' -v limit="$limit" '{
      start = 0; end = 0
      for (i = 4; i <= NF; i++) { if ($i ~ /^line:/) start = substr($i, 6); if ($i ~ /^end:/) end = substr($i, 5) }
      if (end - start + 1 > limit) printf "%s:%s: %s is %d lines\n", $2, start, $1, end - start + 1
    }' | sort)
if [ -n "$long" ]; then
  echo "functions in src/ over $limit lines:" >&2
  echo "$long" >&2
  exit 1
fi
echo "no function in src/ is over $limit lines"
