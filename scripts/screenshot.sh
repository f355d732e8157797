#!/usr/bin/env bash
# Screenshot smoke test: opens the app (the virtual rig, default settings, a fresh home) in a
# real window under Xvfb, waits until it has run for a while, takes a screenshot of the screen
# and checks that the window drew something (not a blank screen) and that the app is still
# running (it did not crash or exit with an error).
#
#   scripts/screenshot.sh [BINARY] [OUT.png] [SECONDS]
#
# Defaults: target/debug/tremorscan, docs/screenshot.png, 45 s. Needs xvfb-run, xauth and
# ImageMagick (`import`, `identify`); .ci/run installs them.
set -euo pipefail
cd "$(dirname "$0")/.."
binary=${1:-target/debug/tremorscan}
out=${2:-docs/screenshot.png}
seconds=${3:-45}
home=$(mktemp -d)
log=$(mktemp)
trap 'rm -rf "$home" "$log"' EXIT
[ -x "$binary" ] || { echo "screenshot: no binary at $binary (build it first)" >&2; exit 1; }
out_abs=$(realpath -m "$out")
HOME="$home" XDG_CONFIG_HOME="$home/.config" xvfb-run -a -s "-screen 0 1400x900x24" \
    bash -c '
        "$1" gui --point 210,134 --point 450,190 --point 300,330 >"$2" 2>&1 &
        app=$!
        sleep "$3"
        if ! kill -0 "$app" 2>/dev/null; then
            echo "screenshot: the app exited early" >&2
            exit 1
        fi
        import -window root "$4"
        kill "$app"
        wait "$app" || true
    ' _ "$binary" "$log" "$seconds" "$out_abs" || { cat "$log" >&2; exit 1; }
# A blank or single-colour screen has no spread of values.
spread=$(identify -format '%[fx:standard_deviation]' "$out_abs")
if awk -v s="$spread" 'BEGIN { exit !(s < 0.02) }'; then
    echo "screenshot: the screen is blank (standard deviation $spread)" >&2
    cat "$log" >&2
    exit 1
fi
if grep -q "panicked" "$log"; then
    echo "screenshot: the app panicked" >&2
    cat "$log" >&2
    exit 1
fi
echo "screenshot: $out_abs (standard deviation $spread)"
