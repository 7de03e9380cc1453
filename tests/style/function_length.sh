#!/usr/bin/env bash
# Every function outside tests/ fits on a screen: at most MAX lines from its signature to
# its closing brace (Universal Ctags' end field). A longer one is a sign that a command
# does its own work or that steps want names; split it.
# Usage: function_length.sh SOURCE_DIR [MAX]
set -euo pipefail
src=${1:?usage: function_length.sh SOURCE_DIR [MAX]}
max=${2:-80}
ctags=$(command -v ctags-universal || command -v ctags || true)
if [ -z "$ctags" ] || ! "$ctags" --version 2>/dev/null | grep -q Universal; then
  echo "function_length.sh: Universal Ctags is needed (Debian package universal-ctags)" >&2
  exit 2
fi
cd "$src"
files=$(find . -path ./tests -prune -o -path './build*' -prune -o -path ./.git -prune -o \
          \( -name '*.cc' -o -name '*.h' \) -print | sed 's#^\./##' | sort)
long=$("$ctags" -x --_xformat='%{line}	%{end}	%{input}	%{name}' --kinds-C++=f \
         --fields=+ne -o - $files 2>/dev/null |
       awk -F'\t' -v max="$max" '$2 != "" && $2 - $1 + 1 > max {
         printf "%s:%s: %s is %d lines (at most %d)\n", $3, $1, $4, $2 - $1 + 1, max }')
n=$(printf '%s\n' "$files" | wc -l)
if [ -n "$long" ]; then
  printf '%s\n' "$long"
  echo "function_length.sh: $(printf '%s\n' "$long" | wc -l) function(s) over $max lines in $n files"
  exit 1
fi
echo "function_length.sh: no function over $max lines in $n files"
