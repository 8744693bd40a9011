#!/usr/bin/env bash
# Build a real gz-transport 13 peer (Gazebo Harmonic): gz-cmake3, gz-utils2, gz-tools2, gz-math7,
# gz-msgs10 and gz-transport13 from their upstream tags into one prefix, with the `gz topic` CLI.
#
# Usage: bench/gz_peer/build.sh [SOURCE_DIR]
#   SOURCE_DIR (or $GZ_PEER_SRC) holds one git repository per upstream project, named like the
#   upstream repository (gz-cmake, gz-utils, gz-tools, gz-math, gz-msgs, gz-transport); checkouts
#   or bare repositories, they only need the tags. Without it, the repositories are cloned from
#   $GZ_PEER_GIT_BASE (default https://github.com/gazebosim) into the cache.
#   The checkouts are not touched: each tag is exported with `git archive`.
#
# Settings (environment):
#   GZ_PEER_PREFIX   install prefix (default ${XDG_CACHE_HOME:-~/.cache}/viewer-bridge/gz13)
#   GZ_CMAKE_TAG GZ_UTILS_TAG GZ_TOOLS_TAG GZ_MATH_TAG GZ_MSGS_TAG GZ_TRANSPORT_TAG   the tags
#   GZ_PEER_JOBS     parallel jobs (default: nproc)
#   GZ_PEER_NO_APT=1 do not install Debian's build dependencies, only report missing ones
#
# Writes <prefix>/env.sh (source it: PATH, LD_LIBRARY_PATH, GZ_CONFIG_PATH for `gz topic`) and
# <prefix>/BUILT (project, tag, commit). A second run with the same tags rebuilds nothing.
# Not part of ./dev test. Run it niced if the machine is shared: nice -n 19 bench/gz_peer/build.sh
set -euo pipefail

say() { printf '[gz_peer] %s\n' "$*"; }
die() { printf '[gz_peer] error: %s\n' "$*" >&2; exit 1; }

cache="${XDG_CACHE_HOME:-$HOME/.cache}/viewer-bridge"
prefix="${GZ_PEER_PREFIX:-$cache/gz13}"
workdir="$cache/gz13-build"
src="${1:-${GZ_PEER_SRC:-}}"
git_base="${GZ_PEER_GIT_BASE:-https://github.com/gazebosim}"
parallel="${GZ_PEER_JOBS:-$(nproc)}"

# Build order matters: each project finds the ones before it in the prefix.
projects=(gz-cmake gz-utils gz-tools gz-math gz-msgs gz-transport)
declare -A tags=(
  [gz-cmake]="${GZ_CMAKE_TAG:-gz-cmake3_3.6.0}"
  [gz-utils]="${GZ_UTILS_TAG:-gz-utils2_2.2.1}"
  [gz-tools]="${GZ_TOOLS_TAG:-gz-tools2_2.0.3}"
  [gz-math]="${GZ_MATH_TAG:-gz-math7_7.6.0}"
  [gz-msgs]="${GZ_MSGS_TAG:-gz-msgs10_10.4.0}"
  [gz-transport]="${GZ_TRANSPORT_TAG:-gz-transport13_13.5.0}"
)
apt_packages=(cmake g++ pkg-config ruby ruby-dev libprotobuf-dev protobuf-compiler libprotoc-dev
  libzmq3-dev cppzmq-dev uuid-dev libsqlite3-dev libtinyxml2-dev libeigen3-dev python3-protobuf git)

# Python for gz-msgs' code generator: Debian's, which has python3-protobuf (not a pyenv/venv one).
python="${GZ_PEER_PYTHON:-/usr/bin/python3}"
[[ -x "$python" ]] || python="$(command -v python3)"
cmake_flags=(
  -DCMAKE_BUILD_TYPE=Release
  -DCMAKE_INSTALL_PREFIX="$prefix"
  -DCMAKE_PREFIX_PATH="$prefix"
  -DCMAKE_INSTALL_LIBDIR=lib
  -DBUILD_TESTING=OFF
  -DBUILD_DOCS=OFF
  -DSKIP_PYBIND11=ON
  -DSKIP_SWIG=ON
  -DPython3_EXECUTABLE="$python"
  -Wno-dev
)
generator=()
command -v ninja >/dev/null && generator=(-G Ninja)

start=$SECONDS

install_build_dependencies() {
  local missing=() package
  for package in "${apt_packages[@]}"; do
    dpkg-query -W -f='${Status}' "$package" 2>/dev/null | grep -q 'install ok installed' \
      || missing+=("$package")
  done
  if ((${#missing[@]} == 0)); then
    say "Debian build dependencies: all present"
    return
  fi
  say "Debian build dependencies missing: ${missing[*]}"
  [[ "${GZ_PEER_NO_APT:-}" == 1 ]] && die "GZ_PEER_NO_APT=1: install them with apt-get first"
  local sudo=()
  if ((EUID != 0)); then
    command -v sudo >/dev/null || die "not root and no sudo: apt-get install ${missing[*]}"
    sudo=(sudo)
  fi
  export DEBIAN_FRONTEND=noninteractive
  "${sudo[@]}" apt-get install -y -q --no-install-recommends "${missing[@]}" \
    || { "${sudo[@]}" apt-get update && "${sudo[@]}" apt-get install -y -q --no-install-recommends "${missing[@]}"; } \
    || die "apt-get install failed for: ${missing[*]}"
  say "installed: ${missing[*]}"
}

# Print the git directory holding $1's tag, cloning (into the cache) when no source dir is given.
repository_for() {
  local project=$1 tag=${tags[$1]} repo
  if [[ -n "$src" ]]; then
    repo="$src/$project"
    [[ -d "$repo" ]] || die "$repo: no such repository (SOURCE_DIR needs one per project: ${projects[*]})"
  else
    repo="$cache/gz13-src/$project"
    if [[ ! -d "$repo" ]]; then
      say "$project: cloning $git_base/$project ($tag)" >&2
      git clone --quiet --bare --depth 1 --branch "$tag" "$git_base/$project" "$repo" >&2 \
        || die "cannot clone $git_base/$project; pass a SOURCE_DIR with local checkouts instead"
    fi
  fi
  if ! git -C "$repo" rev-parse --quiet --verify "refs/tags/$tag^{commit}" >/dev/null; then
    say "$project: tag $tag not in $repo, fetching it from its origin" >&2
    git -C "$repo" fetch --quiet --depth 1 origin "refs/tags/$tag:refs/tags/$tag" >&2 \
      || die "$repo has no tag $tag (list them: git -C $repo tag -l '${project}*')"
  fi
  printf '%s\n' "$repo"
}

# Build and install one project unless the prefix already has this commit built with these flags.
build() {
  local project=$1 tag=${tags[$1]} repo commit stamp key
  repo="$(repository_for "$project")"
  commit="$(git -C "$repo" rev-parse "refs/tags/$tag^{commit}")"
  key="$tag $commit $(printf '%s ' "${cmake_flags[@]}" | sha1sum | cut -c1-12)"
  stamp="$prefix/.built/$project"
  built+=("$(printf '%-13s %-24s %s' "$project" "$tag" "$commit")")
  if [[ "$rebuild_rest" == 0 && -f "$stamp" && "$(cat "$stamp")" == "$key" ]]; then
    say "$project: $tag ($commit) already built, reusing it"
    return
  fi
  rebuild_rest=1  # everything after a rebuilt project is rebuilt against it
  local t0=$SECONDS source="$workdir/src/$project" build="$workdir/build/$project"
  say "$project: building $tag ($commit)"
  rm -rf "$source" "$build" "$stamp"
  mkdir -p "$source" "$build" "$prefix/.built"
  git -C "$repo" archive "$commit" | tar -x -C "$source"
  cmake -S "$source" -B "$build" "${generator[@]}" "${cmake_flags[@]}" >"$build/configure.log" 2>&1 \
    || { tail -n 40 "$build/configure.log" >&2; die "$project: configure failed (log: $build/configure.log)"; }
  cmake --build "$build" --parallel "$parallel" >"$build/build.log" 2>&1 \
    || { tail -n 40 "$build/build.log" >&2; die "$project: build failed (log: $build/build.log)"; }
  cmake --install "$build" >"$build/install.log" 2>&1 \
    || { tail -n 40 "$build/install.log" >&2; die "$project: install failed (log: $build/install.log)"; }
  printf '%s\n' "$key" >"$stamp"
  say "$project: done in $((SECONDS - t0)) s"
}

write_env() {
  cat >"$prefix/env.sh" <<EOF
# Source this for the gz-transport 13 peer built by bench/gz_peer/build.sh: gz topic -l/-i/-e/-p
export GZ_PEER_PREFIX="$prefix"
export PATH="$prefix/bin\${PATH:+:\$PATH}"
export LD_LIBRARY_PATH="$prefix/lib\${LD_LIBRARY_PATH:+:\$LD_LIBRARY_PATH}"
export GZ_CONFIG_PATH="$prefix/share/gz"
EOF
}

say "prefix: $prefix"
say "sources: ${src:-clone from $git_base}"
[[ -z "$src" || -d "$src" ]] || die "$src: not a directory"
install_build_dependencies
export PKG_CONFIG_PATH="$prefix/lib/pkgconfig${PKG_CONFIG_PATH:+:$PKG_CONFIG_PATH}"
export CMAKE_PREFIX_PATH="$prefix${CMAKE_PREFIX_PATH:+:$CMAKE_PREFIX_PATH}"
mkdir -p "$prefix" "$workdir"
rebuild_rest=0
built=()
for project in "${projects[@]}"; do
  build "$project"
done
printf '%s\n' "${built[@]}" >"$prefix/BUILT"
write_env

source "$prefix/env.sh"
gz topic --help >/dev/null 2>&1 || die "'gz topic' does not run with $prefix/env.sh (GZ_CONFIG_PATH=$GZ_CONFIG_PATH)"
say "built (project, tag, commit), also in $prefix/BUILT:"
sed 's/^/  /' "$prefix/BUILT"
say "took $((SECONDS - start)) s"
say "use it: source $prefix/env.sh && gz topic -l"
