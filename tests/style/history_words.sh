#!/usr/bin/env bash
# The repository speaks to its users about the project, not about how it came to be:
# no file tells the story of its own development (its work periods, its tracker entries).
# (The pattern is built from pieces so that this file does not match itself.)
# Usage: history_words.sh SOURCE_DIR
set -euo pipefail
src=${1:?usage: history_words.sh SOURCE_DIR}
word_a='sess''ions?'
word_b='iss''ue [0-9]+'
pattern="\\b${word_a}\\b|\\b${word_b}"
cd "$src"
if git rev-parse --is-inside-work-tree >/dev/null 2>&1; then
  hits=$(git grep -I -n -i -E "$pattern" -- . || true)
else
  hits=$(grep -r -I -n -i -E "$pattern" --exclude-dir=.git --exclude-dir='build*' . || true)
fi
if [ -n "$hits" ]; then
  printf '%s\n' "$hits"
  echo "history_words.sh: $(printf '%s\n' "$hits" | wc -l) line(s) speak of the development's history"
  exit 1
fi
echo "history_words.sh: none"
