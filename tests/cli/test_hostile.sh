# The hostile-input table: every kind of file loom reads (WIF, PBM, PGM,
# PPM, PNG, mapping file, OBJ, Mitsuba .vol, NRRD with attached and with
# detached data, raw, OpenEXR, .ldb, .loomf), given as a FIFO with no
# writer, /dev/zero, /dev/urandom, a directory, a 2 GB sparse file and a
# file of the right magic followed by garbage: each must exit 1, with a
# message naming the file (and for the non-files "not a regular file"),
# without hanging (tests/cli/childrun kills it after 20 s: a hang guard,
# not a timing assertion) and with a peak RSS below 64 MiB (not checked
# under sanitizers, whose shadow memory alone is larger).
SUITE=hostile
. "$LOOM_TOP/tests/cli/lib.sh"
RUN=$LOOM_BUILD/tests/childrun
RSS_MAX_KIB=65536
H=$T/h
mkdir -p "$H"

if [ ! -x "$RUN" ]; then
	fail childrun "$RUN is missing (make builds it)"
	exit 0
fi

# setup: a database, a fabric and good companions for the inputs under test
DB=$T/db.ldb
"$LOOM" exemplar generate --preset tiny --seed 3 --quiet -o "$DB" &&
"$LOOM" pattern make twill --over 2 --under 3 --size 10x10 -o "$T/tw.pbm" &&
"$LOOM" synth "$T/tw.pbm" --db "$DB" --quiet -o "$T/f.loomf" ||
	{ fail setup "cannot make the database and fabric"; exit 0; }

# garbage NAME PREFIX-HEX: PREFIX followed by the same 64 KiB of
# pseudo-random bytes (fixed seed, no NUL so that text formats get past
# their first check)
python3 -c 'import random, sys
r = random.Random(19)
open(sys.argv[1], "wb").write(bytes(1 + b % 255 for b in r.randbytes(65536)))' "$T/body"
garbage() {
	: >"$1"
	h=$2
	while [ -n "$h" ]; do
		rest=${h#??}
		# shellcheck disable=SC2059
		printf "\\$(printf %o "0x${h%"$rest"}")" >>"$1"
		h=$rest
	done
	cat "$T/body" >>"$1"
}

# make_input KIND PATH: PATH becomes the hostile input KIND
# (the garbage kind needs $MAGIC, the format's first bytes in hex)
make_input() {
	rm -rf "$2"
	case $1 in
	fifo) mkfifo "$2" ;;
	zero) ln -s /dev/zero "$2" ;;
	urandom) ln -s /dev/urandom "$2" ;;
	dir) mkdir "$2" ;;
	sparse) truncate -s 2G "$2" ;;
	garbage) garbage "$2" "$MAGIC" ;;
	esac
}

# check NAME FILE REASON CMD...: CMD exits 1 within the guard, the message
# names FILE and contains REASON, peak RSS below the limit
check() {
	n=$1; file=$2; reason=$3; shift 3
	"$RUN" 20 "$@" >"$T/res" 2>"$T/err" </dev/null
	res=$(tail -n 1 "$T/res")
	set -- $res
	if [ "$1" = timeout ]; then
		fail "$n" "no exit after 20 s (killed)"
		return
	fi
	if [ "$2" != 1 ]; then
		fail "$n" "exit $2, expected 1; stderr: $(head -c 300 "$T/err")"
		return
	fi
	if ! grep -qF -- "$file" "$T/err"; then
		fail "$n" "message does not name $file: $(head -c 300 "$T/err")"
		return
	fi
	if [ -n "$reason" ] && ! grep -qF -- "$reason" "$T/err"; then
		fail "$n" "message lacks '$reason': $(head -c 300 "$T/err")"
		return
	fi
	if [ -z "${LOOM_SAN:-}" ] && [ "$4" -ge "$RSS_MAX_KIB" ]; then
		fail "$n" "peak RSS $4 KiB, limit $RSS_MAX_KIB KiB"
		return
	fi
	pass "$n"
}

# row TYPE EXT MAGIC CMD-WITH-@: one row of the table; @ in the command
# stands for the hostile file (named in.EXT)
row() {
	type=$1; ext=$2; MAGIC=$3; shift 3
	for kind in fifo zero urandom dir sparse garbage; do
		f=$H/in-$type-$kind.$ext
		make_input "$kind" "$f"
		reason=""
		case $kind in fifo|zero|urandom|dir) reason="not a regular file" ;; esac
		cmd=""
		for a in "$@"; do
			[ "$a" = @ ] && a=$f
			cmd="$cmd '$a'"
		done
		eval "check $type-$kind '$f' '$reason' $cmd"
		rm -rf "$f"
	done
}

NO="$T/out.pbm"
row wif wif 5b5749465d0a "$LOOM" pattern info @
row pbm pbm 50340a "$LOOM" pattern info @
row pgm pgm 50350a "$LOOM" pattern info @
row ppm ppm 50360a "$LOOM" pattern info @
row png png 89504e470d0a1a0a "$LOOM" pattern info @
row design pattern 89504e470d0a1a0a "$LOOM" synth @ --db "$DB" --quiet -o "$T/x.loomf"
row mapping map 7961726e20 "$LOOM" pattern from-image "$DATA/images/motif.ppm" --map @ -o "$NO"
row obj obj 762030203020300a "$LOOM" render "$T/f.loomf" --mesh @ --width 8 --height 8 --spp 1 -o "$T/r.png"
row vol vol 564f4c03 "$LOOM" exemplar build @ --warps 2 --wefts 2 --db "$T/b.ldb"
row nrrd nrrd 4e52524430303034 "$LOOM" exemplar build @ --warps 2 --wefts 2 --db "$T/b.ldb"
row raw raw "" "$LOOM" exemplar build @ --raw-dims 32,32,16 --raw-type u8 --warps 2 --wefts 2 --db "$T/b.ldb"
row exr exr 762f3101 --exr @
row ldb ldb 894c44420d0a1a0a "$LOOM" exemplar info @
row loomf loomf 894c46420d0a1a0a "$LOOM" info @

# detached NRRD data files (raw and gzip encodings): the header is fine, the
# data file named in it is the hostile input
for enc in raw gzip; do
	for kind in fifo zero urandom dir sparse garbage; do
		d=$H/data-$enc-$kind
		MAGIC=1f8b08
		make_input "$kind" "$d"
		printf 'NRRD0004\ntype: uint8\ndimension: 3\nsizes: 32 32 16\nencoding: %s\ndata file: %s\n\n' \
		    "$enc" "data-$enc-$kind" >"$H/det-$enc-$kind.nhdr"
		reason=""
		case $kind in fifo|zero|urandom|dir) reason="not a regular file" ;; esac
		check "nhdr-$enc-$kind" "$d" "$reason" "$LOOM" exemplar build "$H/det-$enc-$kind.nhdr" \
		    --warps 2 --wefts 2 --db "$T/b.ldb"
		rm -rf "$d"
	done
done

# the size limits: a mapping file above its limit is refused before it is
# read, and LOOM_MAX_INPUT_BYTES moves the limit of the whole-file readers
head -c 100 /dev/zero | tr '\0' ' ' >"$H/spaces.wif"
LOOM_MAX_INPUT_BYTES=50 "$LOOM" pattern info "$H/spaces.wif" >"$T/out" 2>"$T/err"
rc=$?
if [ $rc -eq 1 ] && grep -qF "100 bytes, more than the limit of 50 bytes for WIF files" "$T/err"; then
	pass size_limit_override; else
	fail size_limit_override "exit $rc: $(head -c 300 "$T/err")"; fi

# a database whose brick data were damaged after the fabric was made: it
# opens (the header, metadata and CRCs of the tables are intact), and the
# commands that read bricks fail on the first bad one with exit 1, naming
# it, and free what they allocated (LeakSanitizer checks under make
# sanitize); the damage is 64 KiB of 0x55 over the start of the brick data
head -c 65536 /dev/zero | tr '\0' 'U' | dd of="$DB" bs=1 seek=128 conv=notrunc 2>/dev/null
expect_exit corrupt_db_scan 1 "$LOOM" scan "$T/f.loomf" --all --reduce checksum --quiet
expect_err_contains corrupt_db_scan_msg "CRC32 mismatch"
expect_exit corrupt_db_export 1 "$LOOM" export "$T/f.loomf" --all --format vol --quiet -o "$T/exp"
expect_err_contains corrupt_db_export_msg "CRC32 mismatch"
expect_exit corrupt_db_verify 1 "$LOOM" exemplar verify "$DB" --quiet
expect_err_contains corrupt_db_verify_msg "brick"
