#!/bin/sh
# usage: expect_exit.sh STATUS TEXT COMMAND...: run COMMAND, pass if it exits with STATUS and
# its stdout+stderr contain TEXT.
want=$1
text=$2
shift 2
out=$("$@" 2>&1)
got=$?
printf '%s\n' "$out"
if [ "$got" -ne "$want" ]; then
    echo "FAIL: exit status $got, expected $want" >&2
    exit 1
fi
case $out in
*"$text"*) ;;
*) echo "FAIL: output does not contain: $text" >&2; exit 1 ;;
esac
exit 0
