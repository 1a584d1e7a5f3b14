#!/bin/sh
# tools/deps.sh - make sure the Debian packages loom needs are installed.
#
#   tools/deps.sh build   libraries and headers needed to compile loom
#   tools/deps.sh test    build + independent readers used by the tests
#   tools/deps.sh slurm   a real single-node Slurm for tests/slurm/run.sh
#                         (slurmctld, slurmd, the client commands, munge)
#   tools/deps.sh openvdb the peer benchmark bench/bench_vdb.cpp (make bench):
#                         OpenVDB, NanoVDB, the Boost headers they include, g++
#   tools/deps.sh fuzz    build + clang with libFuzzer (make fuzz, fuzz-run)
#   tools/deps.sh blender Blender (Cycles) for tests/extra/blender.sh and the
#                         Cycles comparison of bench/cycles.sh; only on request
#   tools/deps.sh paraview ParaView's pvpython and xvfb-run for
#                         tools/paraview/render_nrrd.py; only on request
#
# Missing packages are installed with apt-get (as root, or through sudo -n)
# and named as they are installed.  Where that is impossible the script
# prints one line naming the packages to install and exits 1.
set -u
what=${1:-build}

missing=""
need() { # need PACKAGE TEST-COMMAND...
	pkg=$1; shift
	if ! "$@" >/dev/null 2>&1; then
		missing="$missing $pkg"
	fi
}
has_header() { [ -f "/usr/include/$1" ]; }

if [ "$what" = slurm ]; then
	# only the scheduler: tests/slurm/run.sh runs it on localhost (its
	# daemons are started by the test, never by the packages' services)
	need slurmctld    command -v slurmctld
	need slurmd       command -v slurmd
	need slurm-client command -v sbatch
	need munge        command -v munged
elif [ "$what" = blender ]; then
	need blender        command -v blender
elif [ "$what" = paraview ]; then
	need paraview         command -v paraview
	need python3-paraview command -v pvpython
	need xvfb             command -v xvfb-run
	need xauth            command -v xauth
elif [ "$what" = openvdb ]; then
	need g++            command -v g++
	need libopenvdb-dev has_header openvdb/openvdb.h
	need libnanovdb-dev has_header nanovdb/NanoVDB.h
	need libboost-dev   has_header boost/numeric/conversion/conversion_traits.hpp
else
	need pkg-config      command -v pkg-config
	need libdeflate-dev  has_header libdeflate.h
	need libpng-dev      has_header png.h
	need libopenexr-dev  has_header OpenEXR/openexr.h
	need libembree-dev   has_header embree3/rtcore.h
	# loom serve: the HTTP server, and npm for the viewer page (make runs npm ci)
	need libmicrohttpd-dev has_header microhttpd.h
	need npm             command -v npm
	# the OpenVDB / NanoVDB export (io/volume/vdb_shim.cpp, C++17)
	need g++             command -v g++
	need libopenvdb-dev  has_header openvdb/openvdb.h
	need libnanovdb-dev  has_header nanovdb/NanoVDB.h
	# OpenVDB's headers include Boost's, but Debian's libopenvdb-dev does
	# not depend on libboost-dev: a fresh machine lacks them
	need libboost-dev    has_header boost/numeric/conversion/conversion_traits.hpp
fi
if [ "$what" = fuzz ]; then
	need clang       command -v clang
fi
if [ "$what" = test ]; then
	need openexr     command -v exrheader
	need teem-apps   command -v teem-unu
	# the CLI tests read loom's --json output with python3's json module
	need python3     command -v python3
	# the VDB export read back by OpenVDB's Python module (Debian's python3 only)
	need python3-openvdb /usr/bin/python3 -c 'import pyopenvdb'
	need python3-numpy   /usr/bin/python3 -c 'import numpy'
	# the viewer's end-to-end test: Debian's chromium driven by playwright-core
	need chromium    command -v chromium
	need curl        command -v curl
fi

[ -z "$missing" ] && exit 0

echo "loom: installing missing Debian packages:$missing" >&2
if [ "$(id -u)" = 0 ]; then
	SUDO=""
elif command -v sudo >/dev/null 2>&1 && sudo -n true 2>/dev/null; then
	SUDO="sudo -n"
else
	echo "loom: cannot install packages (not root, no sudo); please run: apt-get install$missing" >&2
	exit 1
fi
if ! command -v apt-get >/dev/null 2>&1; then
	echo "loom: no apt-get on this system; please install:$missing" >&2
	exit 1
fi
export DEBIAN_FRONTEND=noninteractive
# A fresh machine has empty package lists: update once, quietly.
$SUDO apt-get update -qq >&2 || true
# shellcheck disable=SC2086
if ! $SUDO apt-get install -y -qq --no-install-recommends $missing >&2; then
	echo "loom: apt-get failed; please install:$missing" >&2
	exit 1
fi
echo "loom: installed:$missing" >&2
exit 0
