#!/usr/bin/env bash
# expect_error.sh REGEX COMMAND...: passes when COMMAND exits non-zero within 60 s and its output
# matches REGEX (extended grep); a hang, a zero exit or another message fails.
regex=$1
shift
out=$(timeout 60 "$@" 2>&1)
status=$?
if [[ $status -eq 124 ]]; then echo "HANG: no exit within 60 s"; exit 1; fi
if [[ $status -eq 0 ]]; then echo "exit status 0, expected an error"; echo "$out" | tail -5; exit 1; fi
if ! grep -qE -- "$regex" <<<"$out"; then echo "error message does not match '$regex':"; echo "$out" | grep -m3 "ERROR" ; exit 1; fi
echo "OK: exit $status, $(grep -m1 -oE -- "$regex" <<<"$out")"
