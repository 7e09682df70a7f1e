#!/bin/sh
# Runs every tests/cli/test_*.sh; fails if any fails.  Each test prints
# "ok NAME" or explains what went wrong.
set -u
here=$(dirname "$0")
fail=0
for t in "$here"/test_*.sh; do
    if ! sh "$t"; then
        echo "FAIL $(basename "$t")"
        fail=1
    fi
done
[ $fail = 0 ] && echo "cli tests: all passed"
exit $fail
