#!/usr/bin/env bash
# Run a command inside a user-mode Linux guest that has kernel SocketCAN (vcan0 up).
#
#   bash scripts/kernel-can.sh [--results DIR] [--mem 2G] [--] COMMAND [ARGS...]
#   bash scripts/kernel-can.sh                     # default: the kernel_can tests
#
# The guest is Debian's user-mode-linux kernel (`linux.uml`): it boots as an ordinary process
# (no KVM), shares the host's root file system read-only through hostfs, so the project's own
# .venv runs unchanged inside. PID 1 is this same script (called with --guest-init): it mounts
# proc, sys, devtmpfs and tmpfs, mounts DIR read-write (results, caches, builds), loads the
# kernel's vcan/can-raw modules, brings vcan0 up, raises the socket receive buffers, runs the
# command from the project root with the project's .venv and powers off. The command's exit
# status is this script's exit status (2 when the guest could not be set up, with the reason).
#
# Requirements: Debian/Ubuntu with `apt-get install user-mode-linux kmod iproute2`, run as root
# (the guest's root file system is the host's, and the job needs root inside to load modules).
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
SELF="$ROOT/scripts/kernel-can.sh"

if [[ "${1:-}" == "--guest-init" ]]; then
    # ---------------- inside the guest: PID 1 ----------------
    shift
    export PATH=/usr/local/sbin:/usr/local/bin:/usr/sbin:/usr/bin:/sbin:/bin
    # the kernel command line loses quoting (and gains root=/console= words): only the results
    # directory comes through it; the job itself is the file "$results/job" the host wrote
    results="$1"
    status=2
    finish() {
        echo "$status" > "$results/exit_status" 2>/dev/null
        sync
        echo o > /proc/sysrq-trigger
        sleep 10
    }
    trap finish EXIT
    mount -t proc proc /proc
    mount -t sysfs sys /sys
    mount -t devtmpfs dev /dev 2>/dev/null || true
    mount -t tmpfs tmp /tmp
    # a checkout under /tmp (cloned there, or reached through a symlink there) is hidden by
    # that tmpfs: mount it again from the host, read-only as the rest of the root file system
    if [[ "$ROOT" == /tmp/* ]]; then
        mkdir -p "$ROOT"
        mount -r -t hostfs none "$ROOT" -o "$ROOT"
    fi
    mkdir -p /dev/pts /dev/shm
    mount -t devpts devpts /dev/pts 2>/dev/null || true
    mount -t tmpfs shm /dev/shm
    # the results directory is the host's, read-write, through hostfs (under /tmp its mount
    # point is on the guest's fresh tmpfs, so create it first)
    mkdir -p "$results" 2>/dev/null || true
    mount -t hostfs none "$results" -o "$results"
    # reached through a symlink, the checkout's own path is under /tmp too (a clone there):
    # the venv names that path (its activate script, its scripts' #! lines), so mount it as well
    physical="$(cat "$results/root" 2>/dev/null || true)"
    if [[ -n "$physical" && "$physical" != "$ROOT" && "$physical" == /tmp/* ]]; then
        mkdir -p "$physical"
        mount -r -t hostfs none "$physical" -o "$physical"
    fi
    exec >>"$results/guest.log" 2>&1
    kver="$(uname -r)"
    mods="/usr/lib/uml/modules/$kver"
    if [[ ! -d "$mods" ]]; then
        echo "kernel-can: no modules for $kver in /usr/lib/uml/modules" >&2
        exit 2
    fi
    # modprobe looks in ROOT/lib/modules/<version>: give it a root on the tmpfs (the host may
    # have no /lib/modules at all, and the root file system is read-only)
    mkdir -p "/tmp/kmod/lib/modules/$kver"
    mount --bind "$mods" "/tmp/kmod/lib/modules/$kver"
    modprobe -d /tmp/kmod vcan && modprobe -d /tmp/kmod can-raw || {
        echo "kernel-can: modprobe vcan can-raw failed" >&2; exit 2; }
    ip link set lo up
    ip link add dev vcan0 type vcan && ip link set up vcan0 || {
        echo "kernel-can: cannot create vcan0" >&2; exit 2; }
    # the default 208 KiB receive buffer loses frames under emulation
    sysctl -q -w net.core.rmem_default=33554432 net.core.rmem_max=33554432 \
        net.core.wmem_max=33554432
    # the root file system is read-only: every cache and build goes to the results directory
    cache="$2"
    mkdir -p "$cache" 2>/dev/null || true
    mount -t hostfs none "$cache" -o "$cache"
    export HOME="$results/home"
    export XDG_CACHE_HOME="$cache/xdg"
    # the host's compiled modules (__pycache__ on the read-only root) are used as they are: a
    # PYTHONPYCACHEPREFIX would make Python ignore them and compile everything again inside the
    # one-CPU guest, 2-3x a daemon's start-up on a fresh cache (3.5 s against 1.4 s idle,
    # beyond a profile's 10 s boot-up wait on a loaded machine)
    export PYTHONDONTWRITEBYTECODE=1
    export AGRIHIL_CACHE="$cache/agrihil"
    export AGRIHIL_IN_GUEST=1
    export AGRIHIL_VCAN=vcan0
    export TMPDIR=/tmp
    mkdir -p "$HOME" "$XDG_CACHE_HOME" "$AGRIHIL_CACHE"
    if [[ -f "$results/env" ]]; then
        # shellcheck disable=SC1091
        source "$results/env"
    fi
    cd "$ROOT"
    if [[ -x "$ROOT/.venv/bin/python" ]]; then
        # shellcheck disable=SC1091
        source "$ROOT/.venv/bin/activate"
    fi
    echo "kernel-can: guest up ($kver), vcan0 ready; running: $(cat "$results/job")"
    set +e
    bash "$results/job"
    status=$?
    set -e
    echo "kernel-can: command exited $status"
    exit "$status"
fi

# ---------------- on the host ----------------
results=""
mem="2G"
# caches and builds made inside the guest (kept between runs; the guest's root is read-only)
cache="${AGRIHIL_GUEST_CACHE:-${XDG_CACHE_HOME:-$HOME/.cache}/agrihil-guest}"
while [[ $# -gt 0 ]]; do
    case "$1" in
        --results) results="$2"; shift 2 ;;
        --mem) mem="$2"; shift 2 ;;
        --cache) cache="$2"; shift 2 ;;
        --check) check_only=1; shift ;;
        --) shift; break ;;
        *) break ;;
    esac
done

why_not() {
    # prints why the guest cannot start here, and the command that fixes it; empty when it can
    if [[ "$(uname -s)" != "Linux" ]]; then
        echo "user-mode Linux runs on Linux hosts only"; return
    fi
    if [[ ! -r /etc/debian_version ]]; then
        echo "not a Debian-based system: the guest uses Debian's user-mode-linux package"; return
    fi
    if [[ "$(id -u)" != "0" ]]; then
        echo "not root: the guest shares the host's root file system and loads modules;" \
             "run as root (sudo bash scripts/kernel-can.sh ...)"; return
    fi
    local missing=()
    command -v linux.uml >/dev/null 2>&1 || missing+=(user-mode-linux)
    command -v modprobe >/dev/null 2>&1 || missing+=(kmod)
    command -v ip >/dev/null 2>&1 || missing+=(iproute2)
    if [[ ${#missing[@]} -gt 0 ]]; then
        echo "missing ${missing[*]}: apt-get install -y ${missing[*]}" \
             "(or bash scripts/setup.sh --system-packages)"; return
    fi
    if [[ ! -d /usr/lib/uml/modules ]]; then
        echo "no /usr/lib/uml/modules: apt-get install --reinstall -y user-mode-linux"; return
    fi
}

reason="$(why_not)"
if [[ -n "$reason" ]]; then
    echo "kernel-can: cannot start the guest: $reason" >&2
    exit 3
fi
if [[ "${check_only:-0}" == "1" ]]; then
    echo "kernel-can: the guest can start here"
    exit 0
fi
if [[ $# -eq 0 ]]; then
    set -- python -m pytest -q -p no:cacheprovider -m kernel_can tests/kernel
fi

own_results=0
if [[ -z "$results" ]]; then
    results="$(mktemp -d /tmp/agrihil-kernel-can.XXXXXX)"
    own_results=1
fi
mkdir -p "$results" "$cache"
results="$(cd "$results" && pwd)"
cache="$(cd "$cache" && pwd)"
for dir in "$results" "$cache"; do
    if [[ "$dir" =~ [[:space:]] ]]; then
        echo "kernel-can: $dir: the guest's kernel command line cannot carry a path with" \
             "spaces" >&2
        exit 2
    fi
done
rm -f "$results/exit_status" "$results/guest.log"
printf '%q ' "$@" > "$results/job"
(cd "$ROOT" && pwd -P) > "$results/root"   # the checkout's own path, for the guest
echo >> "$results/job"
: > "$results/guest.log"

# UML 6.1 cannot restore FPU state on hosts with a large XSAVE area (AVX-512/AMX): it panics
# with "ptrace set fp regs failed, errno = 14". The shim sizes that buffer from the host.
shim_src="$ROOT/scripts/uml_xstate_shim.c"
shim_dir="${XDG_CACHE_HOME:-$HOME/.cache}/agrihil"
shim="$shim_dir/uml_xstate_shim-$(sha256sum "$shim_src" | cut -c1-16).so"
if [[ ! -f "$shim" ]]; then
    mkdir -p "$shim_dir"
    cc -O2 -Wall -Werror -shared -fPIC -o "$shim.tmp.$$" "$shim_src" || {
        echo "kernel-can: cannot build $shim_src (needs a C compiler)" >&2; exit 2; }
    mv "$shim.tmp.$$" "$shim"
fi

# UML keeps its memory in a file under TMPDIR (must allow exec mappings): /dev/shm or /tmp
uml_tmp="$results/uml-tmp"
mkdir -p "$uml_tmp"
start_ms=$(( $(date +%s%N) / 1000000 ))
set +e
TMPDIR="$uml_tmp" LD_PRELOAD="$shim" linux.uml mem="$mem" rootfstype=hostfs rootflags=/ ro \
    init="$SELF" con=null con0=fd:0,fd:1 quiet -- --guest-init "$results" "$cache" \
    </dev/null >"$results/console.log" 2>&1
uml_rc=$?
set -e
end_ms=$(( $(date +%s%N) / 1000000 ))
rm -rf "$uml_tmp"
cat "$results/guest.log"
if [[ ! -f "$results/exit_status" ]]; then
    echo "kernel-can: the guest ended (linux.uml exit $uml_rc) without an exit status;" \
         "console: $results/console.log" >&2
    tail -n 20 "$results/console.log" >&2
    exit 2
fi
status="$(cat "$results/exit_status")"
elapsed_ms=$(( end_ms - start_ms ))
printf 'kernel-can: guest run took %d.%01d s, exit %s\n' $(( elapsed_ms / 1000 )) \
    $(( elapsed_ms % 1000 / 100 )) "$status" >&2
if [[ $own_results -eq 1 && "$status" == "0" ]]; then
    rm -rf "$results"
fi
exit "$status"
