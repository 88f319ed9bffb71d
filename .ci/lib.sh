# Shared by .ci/run and .ci/services: stop with one line, and install with apt-get when allowed.

die() {
  echo "error: $*" >&2
  exit 1
}

# Whether this run may install packages: a root shell with apt-get, unless CI_NO_INSTALL=1.
can_apt() {
  [ "${CI_NO_INSTALL:-}" != 1 ] && [ "$(id -u)" -eq 0 ] && command -v apt-get >/dev/null 2>&1
}

APT_UPDATED=
apt_install() {  # apt_install WHAT PACKAGE...: install as root, or stop naming WHAT
  can_apt || die "$1 is not installed and this is not a root shell with apt-get: install $1"
  echo "installing $*"
  export DEBIAN_FRONTEND=noninteractive
  if [ -z "$APT_UPDATED" ]; then
    apt-get update -qq >/dev/null || die "apt-get update failed (installing $1)"
    APT_UPDATED=1
  fi
  shift
  apt-get install -y -qq "$@" >/dev/null || die "apt-get install $* failed"
}
