#!/usr/bin/env bash
# Runs a command on QGIS 3.40 LTR (Debian 13 "trixie") in a cached chroot.
#
# Usage: scripts/chroot_qgis340.sh [COMMAND [ARG...]]   (default: an interactive shell)
#
# The chroot is built once with mmdebstrap (a few minutes, about 2 GB) into
# $BSPTRI_TRIXIE_DIR (default /var/cache/bsptriangulate/trixie) and reused.
# The work tree and ../shared are bind-mounted at the same absolute paths as on
# the host, inside a private mount namespace, so nothing stays mounted afterwards.
# Needs root (re-runs itself with sudo otherwise).
set -euo pipefail

REPO=$(cd "$(dirname "$0")/.." && pwd -P)
PARENT=$(dirname "$REPO")
ROOTFS=${BSPTRI_TRIXIE_DIR:-/var/cache/bsptriangulate/trixie}
MIRROR=${BSPTRI_DEBIAN_MIRROR:-http://deb.debian.org/debian}
SECURITY_MIRROR=${BSPTRI_DEBIAN_SECURITY_MIRROR:-http://deb.debian.org/debian-security}
# Changing this list rebuilds the chroot.
PACKAGES=python3-qgis,qgis,python3-venv,python3-pip,python3-numpy,python3-shapely,make,ca-certificates

if [ "$(id -u)" -ne 0 ]; then
    exec sudo --preserve-env=BSPTRI_TRIXIE_DIR,BSPTRI_DEBIAN_MIRROR,PIP_INDEX_URL,PIP_EXTRA_INDEX_URL,http_proxy,https_proxy "$0" "$@"
fi

build_rootfs() {
    if ! command -v mmdebstrap >/dev/null; then
        apt-get update -qq
        DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends mmdebstrap
    fi
    local tmp="$ROOTFS.partial"
    rm -rf "$tmp"
    mkdir -p "$(dirname "$ROOTFS")"
    echo "Building the Debian 13 chroot with QGIS 3.40 in $ROOTFS (once; a few minutes)" >&2
    mmdebstrap --variant=apt --quiet --include="$PACKAGES" trixie "$tmp" \
        "deb $MIRROR trixie main" \
        "deb $MIRROR trixie-updates main" \
        "deb $SECURITY_MIRROR trixie-security main"
    # Machines behind a TLS-inspecting proxy add their CA here; pip inside needs it too.
    if compgen -G "/usr/local/share/ca-certificates/*.crt" >/dev/null; then
        cp /usr/local/share/ca-certificates/*.crt "$tmp/usr/local/share/ca-certificates/"
        chroot "$tmp" update-ca-certificates >/dev/null
    fi
    if [ -f /etc/pip.conf ]; then cp /etc/pip.conf "$tmp/etc/pip.conf"; fi
    echo "$PACKAGES" >"$tmp/.bsptriangulate-packages"
    rm -rf "$ROOTFS"
    mv "$tmp" "$ROOTFS"
}

ensure_rootfs() {
    mkdir -p "$(dirname "$ROOTFS")"
    exec 9>"$ROOTFS.lock"
    flock 9
    if [ "$(cat "$ROOTFS/.bsptriangulate-packages" 2>/dev/null)" != "$PACKAGES" ]; then
        build_rootfs
    fi
    cp /etc/resolv.conf "$ROOTFS/etc/resolv.conf" 2>/dev/null || true
    flock -u 9
}

ensure_rootfs

SHARED=""
if [ -e "$PARENT/shared" ]; then SHARED=$(cd "$PARENT/shared" && pwd -P); fi

# Inside a private mount namespace: mount, then chroot; the mounts vanish with it.
export ROOTFS REPO PARENT SHARED
exec unshare --mount --propagation private bash -euo pipefail -c '
    mount -t proc proc "$ROOTFS/proc"
    mount --rbind /dev "$ROOTFS/dev"
    mount --rbind /sys "$ROOTFS/sys"
    mount -t tmpfs tmpfs "$ROOTFS/tmp"
    mkdir -p "$ROOTFS$PARENT"
    mount -t tmpfs tmpfs "$ROOTFS$PARENT"
    mkdir -p "$ROOTFS$REPO"
    mount --bind "$REPO" "$ROOTFS$REPO"
    if [ -n "$SHARED" ] && [ "$SHARED" != "$REPO" ]; then
        mkdir -p "$ROOTFS$PARENT/shared"
        mount --bind "$SHARED" "$ROOTFS$PARENT/shared"
    fi
    if [ $# -eq 0 ]; then set -- bash; fi
    # A clean environment, plus the host'"'"'s package index and proxy settings where set.
    env_vars=(PATH=/usr/local/sbin:/usr/local/bin:/usr/sbin:/usr/bin:/sbin:/bin HOME=/root
        LANG=C.UTF-8 TERM="${TERM:-dumb}" QT_QPA_PLATFORM=offscreen PIP_DISABLE_PIP_VERSION_CHECK=1)
    for name in CI PIP_INDEX_URL PIP_EXTRA_INDEX_URL PIP_TRUSTED_HOST PIP_DEFAULT_TIMEOUT \
        http_proxy https_proxy no_proxy HTTP_PROXY HTTPS_PROXY NO_PROXY PYTEST_ADDOPTS; do
        if [ -n "${!name:-}" ]; then env_vars+=("$name=${!name}"); fi
    done
    exec chroot "$ROOTFS" /usr/bin/env -i "${env_vars[@]}" \
        bash -c "cd \"\$0\" && exec \"\$@\"" "$REPO" "$@"
' bash "$@"
