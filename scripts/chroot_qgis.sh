#!/usr/bin/env bash
# Runs a command on a newer QGIS than the host's, in a cached Debian 13 "trixie" chroot.
#
# Usage: scripts/chroot_qgis.sh FLAVOUR [COMMAND [ARG...]]   (default: an interactive shell)
#
#   FLAVOUR 340   QGIS 3.40 LTR, Debian 13's own      (chroot $BSPTRI_CHROOT_CACHE/trixie)
#   FLAVOUR 344   QGIS 3.44 from trixie-backports     (chroot $BSPTRI_CHROOT_CACHE/trixie-backports)
#
# Each chroot is built once with mmdebstrap (a few minutes, about 2 GB each) under
# $BSPTRI_CHROOT_CACHE (default /var/cache/bsptriangulate) and reused; each has its own folder
# and lock, so both can be built or used at the same time. The work tree and ../shared are
# bind-mounted at the same absolute paths as on the host, inside a private mount namespace, so
# nothing stays mounted afterwards. Needs root (re-runs itself with sudo otherwise).
set -euo pipefail

FLAVOUR=${1:-}
case "$FLAVOUR" in
    340) NAME=trixie QGIS_FROM=trixie ;;
    344) NAME=trixie-backports QGIS_FROM=trixie-backports ;;
    *)
        echo "usage: $0 340|344 [COMMAND [ARG...]]" >&2
        exit 2
        ;;
esac
shift

REPO=$(cd "$(dirname "$0")/.." && pwd -P)
PARENT=$(dirname "$REPO")
CACHE=${BSPTRI_CHROOT_CACHE:-/var/cache/bsptriangulate}
ROOTFS=$CACHE/$NAME
MIRROR=${BSPTRI_DEBIAN_MIRROR:-http://deb.debian.org/debian}
SECURITY_MIRROR=${BSPTRI_DEBIAN_SECURITY_MIRROR:-http://deb.debian.org/debian-security}
# Changing these lists rebuilds the chroot. QGIS's own packages come from $QGIS_FROM.
PACKAGES=python3-venv,python3-pip,python3-numpy,python3-shapely,make,ca-certificates
QGIS_PACKAGES=python3-qgis,qgis
STAMP="$QGIS_PACKAGES,$PACKAGES"
if [ "$QGIS_FROM" != trixie ]; then STAMP="$STAMP from $QGIS_FROM"; fi

if [ "$(id -u)" -ne 0 ]; then
    exec sudo --preserve-env=BSPTRI_CHROOT_CACHE,BSPTRI_DEBIAN_MIRROR,BSPTRI_DEBIAN_SECURITY_MIRROR,PIP_INDEX_URL,PIP_EXTRA_INDEX_URL,http_proxy,https_proxy "$0" "$FLAVOUR" "$@"
fi

install_mmdebstrap() {
    # One apt-get at a time on the host, whichever chroot is being built.
    exec 8>"$CACHE/.host-apt.lock"
    flock 8
    if ! command -v mmdebstrap >/dev/null; then
        apt-get update -qq
        DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends mmdebstrap
    fi
    flock -u 8
}

build_rootfs() {
    install_mmdebstrap
    local tmp="$ROOTFS.partial"
    local sources=("deb $MIRROR trixie main" "deb $MIRROR trixie-updates main"
        "deb $SECURITY_MIRROR trixie-security main")
    local include=$STAMP
    local hooks=()
    if [ "$QGIS_FROM" != trixie ]; then
        sources+=("deb $MIRROR $QGIS_FROM main")
        include=$PACKAGES
        # As a user would: apt-get install -t trixie-backports qgis python3-qgis.
        hooks=(--customize-hook="chroot \"\$1\" env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends -t $QGIS_FROM ${QGIS_PACKAGES//,/ }")
    fi
    rm -rf "$tmp"
    echo "Building the Debian 13 chroot with QGIS from $QGIS_FROM in $ROOTFS (once; a few minutes)" >&2
    mmdebstrap --variant=apt --quiet --include="$include" "${hooks[@]}" trixie "$tmp" "${sources[@]}"
    # Machines behind a TLS-inspecting proxy add their CA here; pip inside needs it too.
    if compgen -G "/usr/local/share/ca-certificates/*.crt" >/dev/null; then
        cp /usr/local/share/ca-certificates/*.crt "$tmp/usr/local/share/ca-certificates/"
        chroot "$tmp" update-ca-certificates >/dev/null
    fi
    if [ -f /etc/pip.conf ]; then cp /etc/pip.conf "$tmp/etc/pip.conf"; fi
    echo "$STAMP" >"$tmp/.bsptriangulate-packages"
    rm -rf "$ROOTFS"
    mv "$tmp" "$ROOTFS"
}

ensure_rootfs() {
    mkdir -p "$CACHE"
    exec 9>"$ROOTFS.lock"
    flock 9
    if [ "$(cat "$ROOTFS/.bsptriangulate-packages" 2>/dev/null)" != "$STAMP" ]; then
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
