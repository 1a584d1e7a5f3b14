# Module layering (engine/MODULES): every #include "..." of engine/, io/
# and tools/ stays inside its module, names a public header, or follows an
# edge listed in engine/MODULES; no engine object calls a function defined
# under io/ (nm of the objects the build made).
SUITE=layers
. "$LOOM_TOP/tests/cli/lib.sh"
cd "$LOOM_TOP" || exit 1
map=engine/MODULES

# module of a source path, or of an included path (as the compiler resolves
# it: relative to the including file first, then engine/, then the top)
module_of() { # path
	case $1 in
	engine/include/*) echo public ;;
	engine/*) echo "$1" | cut -d/ -f2 ;;
	io/*) echo "io/$(echo "$1" | cut -d/ -f2)" ;;
	tools/*) echo tools ;;
	*) echo other ;;
	esac
}
allowed() { # from to
	[ "$1" = "$2" ] && return 0
	[ "$2" = public ] && return 0
	sed -n "s/^$(echo "$1" | sed 's|/|\\/|g'):\(.*\)$/ \1 /p" "$map" | grep -q " $2 "
}

bad=""
n=0
for f in $(find engine io tools -name '*.c' -o -name '*.h' -o -name '*.cpp' | sort); do
	from=$(module_of "$f")
	dir=$(dirname "$f")
	for inc in $(sed -n 's/^[[:space:]]*#[[:space:]]*include[[:space:]]*"\([^"]*\)".*/\1/p' "$f"); do
		n=$((n + 1))
		if [ -f "$dir/$inc" ]; then p="$dir/$inc"
		elif [ -f "engine/include/$inc" ]; then p="engine/include/$inc"
		elif [ -f "engine/$inc" ]; then p="engine/$inc"
		elif [ -f "$inc" ]; then p="$inc"
		else bad="$bad $f:$inc(unresolved)"; continue; fi
		p=$(realpath --relative-to=. "$p")
		to=$(module_of "$p")
		if ! allowed "$from" "$to"; then bad="$bad $f->$p"; fi
	done
done
if [ -z "$bad" ] && [ "$n" -gt 100 ]; then pass includes_follow_modules; else
	fail includes_follow_modules "edges not in $map ($n includes):$bad"; fi

# The rule above, in words users of the tree rely on.
e2io=$(grep -rlE '^[[:space:]]*#[[:space:]]*include[[:space:]]*"(\.\./)*(io|tools)/' engine || true)
if [ -z "$e2io" ]; then pass engine_includes_no_io; else fail engine_includes_no_io "$e2io"; fi

# Every module folder is in the map, and every module in the map exists.
miss=""
for d in engine/*/ io/*/; do
	m=$(module_of "${d%/}/x")
	[ "$m" = public ] && continue
	grep -q "^$m:" "$map" || miss="$miss $m"
done
for m in $(sed -n 's/^\([a-z/]*\):.*/\1/p' "$map"); do
	case $m in tools) [ -d tools ] ;; io/*) [ -d "$m" ] ;; *) [ -d "engine/$m" ] ;; esac || miss="$miss $m(no folder)"
done
if [ -z "$miss" ]; then pass map_matches_tree; else fail map_matches_tree "$miss"; fi

# Link level: an engine object may use only symbols defined by engine
# objects, the C library and its dependencies, never one from io/.
obj=$LOOM_BUILD/obj
if [ -d "$obj/engine" ] && [ -d "$obj/io" ]; then
	# the objects of today's sources (a build tree may hold stale ones)
	objs() { for c in $(ls $1/*/*.c); do echo "$obj/${c%.c}.o"; done; }
	nm --defined-only $(objs io) | awk '$2 ~ /^[TDBR]$/ {print $3}' | sort -u >"$T/iodefs"
	nm -u $(objs engine) | awk '{print $NF}' | sort -u >"$T/used"
	calls=$(comm -12 "$T/iodefs" "$T/used")
	if [ -z "$calls" ]; then pass engine_calls_no_io; else fail engine_calls_no_io "$(echo $calls | head -c 300)"; fi
else
	fail engine_calls_no_io "no objects under $obj"
fi
