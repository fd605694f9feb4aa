#!/usr/bin/env bash
# Install agrihil and its test tools from the project's own files (pyproject.toml).
# Idempotent; uses a virtualenv at .venv unless AGRIHIL_NO_VENV=1 (then the current Python).
#
# System packages (Chromium for the report's browser test; user-mode-linux, kmod and iproute2
# for the kernel CAN guest, scripts/kernel-can.sh; can-utils for the bus log's asc2log check,
# with the de_DE locale asc2log reads ASC dates through) are installed with apt only when asked:
#   bash scripts/setup.sh --system-packages     (explicitly), or
#   CI=1, running as root with apt-get          (a CI job on a Debian-based image).
# Otherwise nothing is installed system-wide; the script says what is missing and how to add it.
# --no-system-packages turns the CI case off.
set -euo pipefail
cd "$(dirname "$0")/.."

SYSTEM_PACKAGES=(chromium user-mode-linux kmod iproute2 can-utils locales)
system="auto"
for arg in "$@"; do
    case "$arg" in
        --system-packages) system="yes" ;;
        --no-system-packages) system="no" ;;
        -h|--help) sed -n '2,12p' "$0"; exit 0 ;;
        *) echo "setup.sh: unknown argument '$arg' (known: --system-packages," \
                "--no-system-packages)" >&2; exit 2 ;;
    esac
done

missing_system_packages() {
    local pkg missing=()
    for pkg in "${SYSTEM_PACKAGES[@]}"; do
        if ! dpkg-query -W -f='${Status}' "$pkg" 2>/dev/null | grep -q "install ok installed"; then
            missing+=("$pkg")
        fi
    done
    echo "${missing[*]}"
}

install_system_packages() {
    if ! command -v apt-get >/dev/null 2>&1 || ! command -v dpkg-query >/dev/null 2>&1; then
        echo "setup.sh: system packages need apt (Debian/Ubuntu); install by hand:" \
             "${SYSTEM_PACKAGES[*]}" >&2
        return 1
    fi
    local missing
    missing="$(missing_system_packages)"
    if [[ -z "$missing" ]]; then
        return 0
    fi
    local sudo=()
    if [[ "$(id -u)" != "0" ]]; then
        if ! command -v sudo >/dev/null 2>&1; then
            echo "setup.sh: installing $missing needs root (no sudo here)" >&2
            return 1
        fi
        sudo=(sudo)
    fi
    echo "setup.sh: installing system packages: $missing" >&2
    # shellcheck disable=SC2086
    "${sudo[@]}" env DEBIAN_FRONTEND=noninteractive apt-get update -q >/dev/null
    # shellcheck disable=SC2086
    "${sudo[@]}" env DEBIAN_FRONTEND=noninteractive apt-get install -y -q --no-install-recommends $missing
}

# can-utils' asc2log reads an ASC file's 24-hour date line with setlocale(LC_TIME, "de_DE") and,
# without that locale, stamps the log with the current time (tests/hil/record/test_buslog_time.py)
make_asc2log_locale() {
    if locale -a 2>/dev/null | grep -qx 'de_DE'; then
        return 0
    fi
    local sudo=()
    if [[ "$(id -u)" != "0" ]]; then sudo=(sudo); fi
    echo "setup.sh: making the de_DE locale for asc2log (localedef)" >&2
    "${sudo[@]}" localedef -i de_DE -f ISO-8859-1 de_DE
}

case "$system" in
    yes)
        install_system_packages
        make_asc2log_locale
        ;;
    auto)
        if [[ -n "${CI:-}" && "$(id -u)" == "0" ]] && command -v apt-get >/dev/null 2>&1; then
            install_system_packages
            make_asc2log_locale
        elif command -v dpkg-query >/dev/null 2>&1; then
            missing="$(missing_system_packages)"
            if [[ -n "$missing" ]]; then
                echo "setup.sh: not installed: $missing (their tests will skip, saying why);" \
                     "add them with: bash scripts/setup.sh --system-packages" >&2
            fi
        fi
        ;;
esac

if [[ "${AGRIHIL_NO_VENV:-0}" != "1" ]]; then
    if [[ ! -x .venv/bin/python ]]; then
        python3 -m venv .venv
    fi
    # shellcheck disable=SC1091
    source .venv/bin/activate
fi
python -m pip install --quiet --upgrade pip
python -m pip install --quiet -e '.[dev]'
