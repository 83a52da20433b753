#!/usr/bin/env bash
# The servers and programs the test suite talks to (Debian/Ubuntu): a local PostgreSQL for
# the run catalogue's shared-lab tests, and Debian's chromium for the lab page's browser
# tests (tests/web: Playwright drives this browser; it never downloads one). Installs Debian's postgresql when missing, starts its
# cluster (creating one when there is none), and makes a role for the user running the
# tests (peer authentication over the local socket, no password) that may create
# databases; the tests create and drop their own databases. Idempotent. Uses sudo when
# not root. Prints the URL the tests use (TSA_BENCH_TEST_POSTGRES overrides it).
set -euo pipefail

if [ "$(id -u)" -eq 0 ]; then
    SUDO=()
elif command -v sudo >/dev/null 2>&1; then
    SUDO=(sudo)
else
    echo "setup-test-services: need root (or sudo) for PostgreSQL and chromium; their tests will be skipped" >&2
    exit 0
fi
as_postgres() { ${SUDO[@]+"${SUDO[@]}"} su postgres -s /bin/sh -c "$1"; }

missing=()
if ! command -v pg_lsclusters >/dev/null 2>&1 || ! ls /usr/lib/postgresql/*/bin/postgres >/dev/null 2>&1; then
    missing+=(postgresql)
fi
[ -x /usr/bin/chromium ] || missing+=(chromium fonts-liberation)   # the fonts: text on the page, not boxes
if [ ${#missing[@]} -gt 0 ]; then
    echo "installing: ${missing[*]}"
    export DEBIAN_FRONTEND=noninteractive
    ${SUDO[@]+"${SUDO[@]}"} apt-get update -q
    ${SUDO[@]+"${SUDO[@]}"} apt-get install -y -q --no-install-recommends "${missing[@]}"
fi

version=$(ls /usr/lib/postgresql | sort -V | tail -1)
if ! pg_lsclusters -h | awk '{print $1"/"$2}' | grep -q "^$version/main$"; then
    ${SUDO[@]+"${SUDO[@]}"} pg_createcluster "$version" main
fi
if ! pg_lsclusters -h | awk -v v="$version" '$1==v && $2=="main" {print $4}' | grep -q online; then
    ${SUDO[@]+"${SUDO[@]}"} pg_ctlcluster "$version" main start
fi
for _ in $(seq 1 50); do
    as_postgres "psql -qAtc 'select 1'" >/dev/null 2>&1 && break
    sleep 0.2
done

user=$(id -un)
if [ "$(as_postgres "psql -qAtc \"select 1 from pg_roles where rolname = '$user'\"")" != "1" ]; then
    as_postgres "createuser --createdb '$user'"
fi
if [ "$(as_postgres "psql -qAtc \"select 1 from pg_database where datname = 'tsa_bench_test'\"")" != "1" ]; then
    as_postgres "createdb -O '$user' tsa_bench_test"
fi
echo "PostgreSQL $version running: postgresql:///tsa_bench_test?host=/var/run/postgresql (user $user)"
/usr/bin/chromium --version 2>/dev/null || true
