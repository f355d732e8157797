#!/usr/bin/env bash
# Checks a built tremorscan .deb: its control fields, that it installs the binary, the desktop
# entry, the icons and the udev rules at their places, that the desktop entry is valid, and that
# the packaged binary runs.
#
#   scripts/check-deb.sh target/debian/tremorscan_*.deb
set -euo pipefail
deb=${1:?usage: scripts/check-deb.sh PACKAGE.deb}
fail() { echo "check-deb: $*" >&2; exit 1; }
[ -f "$deb" ] || fail "no package at $deb"
[ "$(dpkg-deb -f "$deb" Package)" = tremorscan ] || fail "package name is not tremorscan"
contents=$(dpkg-deb -c "$deb")
for path in ./usr/bin/tremorscan \
    ./usr/share/applications/tremorscan.desktop \
    ./usr/share/icons/hicolor/scalable/apps/tremorscan.svg \
    ./usr/share/icons/hicolor/256x256/apps/tremorscan.png \
    ./lib/udev/rules.d/60-tremorscan.rules; do
    grep -q " $path\$" <<<"$contents" || fail "$path is missing from the package"
done
grep -q ' ./usr/bin/tremorscan$' <<<"$(grep '^-rwxr-xr-x' <<<"$contents")" ||
    fail "usr/bin/tremorscan is not executable"
dir=$(mktemp -d)
trap 'rm -rf "$dir"' EXIT
dpkg-deb -x "$deb" "$dir"
dpkg-deb -e "$deb" "$dir/DEBIAN"
[ -x "$dir/DEBIAN/postinst" ] || fail "the postinst script is missing"
grep -q 'udevadm trigger' "$dir/DEBIAN/postinst" || fail "postinst does not apply the udev rules"
if command -v desktop-file-validate >/dev/null 2>&1; then
    desktop-file-validate "$dir/usr/share/applications/tremorscan.desktop"
fi
if command -v udevadm >/dev/null 2>&1; then
    # udevadm verify (systemd 254+) checks rule syntax; older versions lack it.
    if udevadm verify --help >/dev/null 2>&1; then
        udevadm verify "$dir/lib/udev/rules.d/60-tremorscan.rules"
    fi
fi
"$dir/usr/bin/tremorscan" --version | grep -q '^tremorscan ' || fail "the packaged binary does not run"
echo "check-deb: $deb is complete ($(dpkg-deb -f "$deb" Version), $(du -h "$deb" | cut -f1))"
