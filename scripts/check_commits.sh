#!/usr/bin/env bash
# Fails if a commit after the rule began has a subject longer than 72
# characters (CONTRIBUTING.md "Commits"): `git log --oneline` must read as a
# list, with the measurements and reasons in the bodies. Commits up to
# $rule_start predate the rule and are not checked.
#
#   scripts/check_commits.sh [REV]   # default HEAD
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
rule_start=8155af66631203c2cda596580e899802f0f02e96
rev="${1:-HEAD}"
max=72
if ! git rev-parse -q --verify "$rev^{commit}" >/dev/null; then
  echo "check_commits: $rev is not a commit" >&2
  exit 2
fi
if git cat-file -e "$rule_start^{commit}" 2>/dev/null; then
  range="$rule_start..$rev"
else
  range="-1 $rev"  # a shallow clone without the rule's start: the newest commit alone
fi
bad=0 n=0
while IFS= read -r line; do
  hash=${line%% *} subject=${line#* }
  n=$((n + 1))
  if ((${#subject} > max)); then
    echo "check_commits: ${hash:0:10}: subject of ${#subject} characters (at most $max): $subject" >&2
    bad=1
  fi
done < <(git log --format='%H %s' $range)
if ((bad)); then exit 1; fi
echo "check_commits: $n commit subject(s) of at most $max characters"
