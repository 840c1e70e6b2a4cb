#!/usr/bin/env bash
# The PIC16F690 toolchain of firmware/ (`make toolchain`), from the package registries only:
#
#   - gputils (gpasm, gplink, gplib; its p16f690.inc) and gpsim, from Debian;
#   - sdcc with only the pic14 port, built from Debian's sdcc source package (Debian's
#     binary sdcc is configured with --disable-pic14-port) into a cache prefix outside the
#     repository: ${SWARM_SDCC_PIC_PREFIX:-${XDG_CACHE_HOME:-$HOME/.cache}/swarm-formation/sdcc-pic};
#   - the device files sdcc's pic14 port expects and the dfsg source lacks (non-free
#     headers and device libraries): pic16f690.h and pic16f690.lib, generated from
#     gputils' p16f690.inc by scripts/inc2h.py and installed under PREFIX/share/sdcc/non-free.
#
# Idempotent: with a working cached sdcc (pic14) and device library it only checks (a
# second or two). A cold run takes about two minutes on 2 cores. Needs root (or sudo) only
# when Debian packages are missing.
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
PREFIX="${SWARM_SDCC_PIC_PREFIX:-${XDG_CACHE_HOME:-$HOME/.cache}/swarm-formation/sdcc-pic}"
WORK="${PREFIX}.build"
HEADERS=/usr/share/gputils/header
DEVICE=16f690
# Devices sdcc's own pic14 libraries are compiled for (device/lib/pic14: ARCH, EARCH).
LIB_DEVICES="16f877 16f1788"
PACKAGES="gputils gpsim bison flex g++ make libboost-dev zlib1g-dev dpkg-dev xz-utils python3"
PORTS_OFF="mcs51 z80 z180 r2k r2ka r3ka sm83 tlcs90 ez80_z80 z80n ds390 ds400 pic16 hc08 s08
  stm8 pdk13 pdk14 pdk15 mos6502"
JOBS="${JOBS:-2}"

say() { echo "toolchain: $*"; }
die() { echo "toolchain: FAILED: $*" >&2; exit 1; }

as_root() {
  if [ "$(id -u)" -eq 0 ]; then "$@"
  elif command -v sudo >/dev/null && sudo -n true 2>/dev/null; then sudo "$@"
  else die "needs root to run: $*"; fi
}

sdcc_ok() {
  [ -x "$PREFIX/bin/sdcc" ] && "$PREFIX/bin/sdcc" --version 2>/dev/null | grep pic14 >/dev/null \
    && [ -f "$PREFIX/share/sdcc/lib/pic14/libsdcc.lib" ]
}

device_ok() {
  local lib="$PREFIX/share/sdcc/non-free/lib/pic14/pic$DEVICE.lib"
  [ -f "$lib" ] && [ -f "$PREFIX/share/sdcc/non-free/include/pic14/pic$DEVICE.h" ] \
    && [ "$lib" -nt "$ROOT/scripts/inc2h.py" ]
}

# 1. Debian packages.
missing=""
for p in $PACKAGES; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep "install ok installed" >/dev/null \
    || missing="$missing $p"
done
if [ -n "$missing" ]; then
  command -v apt-get >/dev/null || die "no apt-get; install by hand:$missing"
  say "apt-get install$missing"
  as_root apt-get update -qq
  as_root env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends \
    $missing >/dev/null
fi

if sdcc_ok && device_ok; then
  say "ready: $("$PREFIX/bin/sdcc" --version | head -1) in $PREFIX; $(gpsim --version 2>&1 | head -1)"
  exit 0
fi

# 2. sdcc with only the pic14 port, from Debian's source package.
if ! sdcc_ok; then
  start=$SECONDS
  if ! apt-cache showsrc sdcc 2>/dev/null | grep "^Package: sdcc" >/dev/null; then
    codename="$(. /etc/os-release && echo "${VERSION_CODENAME:-bookworm}")"
    say "adding a deb-src entry for $codename (/etc/apt/sources.list.d/swarm-formation-deb-src.sources)"
    printf 'Types: deb-src\nURIs: http://deb.debian.org/debian\nSuites: %s\nComponents: main\nSigned-By: /usr/share/keyrings/debian-archive-keyring.gpg\n' \
      "$codename" | as_root tee /etc/apt/sources.list.d/swarm-formation-deb-src.sources >/dev/null
    as_root apt-get update -qq
  fi
  rm -rf "$WORK"
  mkdir -p "$WORK"
  say "fetching Debian's sdcc source package into $WORK"
  (cd "$WORK" && apt-get source -qq sdcc >/dev/null 2>&1) || die "apt-get source sdcc"
  src="$(find "$WORK" -mindepth 1 -maxdepth 1 -type d -name 'sdcc-*' | head -1)"
  [ -n "$src" ] || die "no sdcc source tree in $WORK"
  cd "$src"
  disable=""
  for p in $PORTS_OFF; do disable="$disable --disable-$p-port"; done
  say "configuring $(basename "$src") with only the pic14 port"
  # shellcheck disable=SC2086
  ./configure --prefix="$PREFIX" $disable --disable-ucsim --disable-sdcdb \
    --disable-sdbinutils --disable-packihx --disable-non-free --disable-doc \
    >"$WORK/configure.log" 2>&1 || die "configure (log: $WORK/configure.log)"
  # 4.2.0's top Makefile builds sdbinutils even when disabled; the pic14 port needs none.
  sed -i 's/^sdcc-libs: sdcc-sdbinutils$/sdcc-libs:/' Makefile
  # The unpacked tree has config.h.in older than configure.ac: keep automake from
  # regenerating the pic14 library's build files (autoheader is not installed).
  (cd device/lib/pic14 && touch aclocal.m4 && touch configure config.h.in \
    && find . -name Makefile.in -exec touch {} +)
  # sdcc's pic14 libc includes <pic16regs.h> -> the default devices' headers (non-free).
  for d in $LIB_DEVICES; do
    python3 "$ROOT/scripts/inc2h.py" "$HEADERS/p$d.inc" device/non-free/include/pic14 >/dev/null
  done
  say "building sdcc (pic14) with -j$JOBS (log: $WORK/build.log)"
  make -j"$JOBS" >"$WORK/build.log" 2>&1 || die "make (log: $WORK/build.log)"
  [ -f device/lib/build/pic14/libsdcc.lib ] || die "pic14 libsdcc.lib not built (log: $WORK/build.log)"
  make install >"$WORK/install.log" 2>&1 || die "make install (log: $WORK/install.log)"
  cd "$ROOT"
  rm -rf "$WORK"
  sdcc_ok || die "$PREFIX/bin/sdcc does not report pic14"
  say "sdcc built in $((SECONDS - start)) s"
fi

# 3. Device header and library of the PIC16F690, from gputils' p16f690.inc.
inc="$PREFIX/share/sdcc/non-free/include/pic14"
lib="$PREFIX/share/sdcc/non-free/lib/pic14"
mkdir -p "$inc" "$lib"
tmp="$(mktemp -d)"
trap 'rm -rf "$tmp"' EXIT
python3 "$ROOT/scripts/inc2h.py" "$HEADERS/p$DEVICE.inc" "$tmp" >/dev/null
cp "$tmp/pic$DEVICE.h" "$inc/"
(cd "$tmp" && "$PREFIX/bin/sdcc" -mpic14 -p"$DEVICE" --use-non-free -c "pic$DEVICE.c" \
  -o "pic$DEVICE.o" >/dev/null && gplib -c "pic$DEVICE.lib" "pic$DEVICE.o") \
  || die "compiling the pic$DEVICE device library"
cp "$tmp/pic$DEVICE.lib" "$lib/"
device_ok || die "device files missing in $PREFIX"
say "ready: $("$PREFIX/bin/sdcc" --version | head -1) in $PREFIX, device pic$DEVICE"
