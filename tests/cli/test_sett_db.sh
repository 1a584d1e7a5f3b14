# `loom synth DRAFT` without --db on a draft that states its sett: a
# database generated for that sett, cached by its parameters in a bounded
# cache directory; with --db, a crossing-aspect mismatch is a warning.
SUITE=sett_db
. "$LOOM_TOP/tests/cli/lib.sh"
W=$LOOM_TOP/tests/data/wif
export LOOM_CACHE_DIR="$T/cache"
unset LOOM_DB
block_of() { # DB -> "b1 b2 b3"
	"$LOOM" exemplar info "$1" --json | python3 -c \
		'import json,sys; print(*json.load(sys.stdin)["block"])'
}
db_of() { # FABRIC -> database path it records
	"$LOOM" info "$1" --json | python3 -c \
		'import json,sys; print(json.load(sys.stdin)["database"]["path"])'
}

# square sett: generated once, square crossings, recorded in the fabric
expect_ok synth_square "$LOOM" synth "$W/sett-square.wif" -o "$T/a.loomf"
expect_err_contains synth_square_generated "generated $T/cache/sett-"
n=$(ls "$T/cache" | grep -c '^sett-.*\.ldb$')
if [ "$n" = 1 ]; then pass cache_one_file; else fail cache_one_file "$n files: $(ls "$T/cache")"; fi
DB=$(ls "$T/cache"/sett-*.ldb)
b=$(block_of "$DB")
case "$b" in "16 16 "*) pass square_block ;; *) fail square_block "$b" ;; esac
p=$(db_of "$T/a.loomf")
if [ "$p" = "$DB" ]; then pass fabric_records_db; else fail fabric_records_db "$p"; fi
# second run: the cached file, unchanged
cp "$DB" "$T/before.ldb"
expect_ok synth_cached "$LOOM" synth "$W/sett-square.wif" -o "$T/b.loomf"
expect_err_contains synth_cached_msg "(cached)"
expect_same cached_unchanged "$DB" "$T/before.ldb"
expect_same cached_same_fabric "$T/a.loomf" "$T/b.loomf"
# a preview reads the fabric through the cached database
expect_ok preview "$LOOM" preview "$T/a.loomf" -o "$T/a.png" --quiet
# 2:1 sett: another key, 2:1 crossings (finer side 16 voxels)
expect_ok synth_two_one "$LOOM" synth "$W/sett-two-one.wif" -o "$T/c.loomf" --quiet
n=$(ls "$T/cache" | grep -c '^sett-.*\.ldb$')
if [ "$n" = 2 ]; then pass cache_two_files; else fail cache_two_files "$n files"; fi
b=$(block_of "$(db_of "$T/c.loomf")")
case "$b" in "16 32 "*) pass two_one_block ;; *) fail two_one_block "$b" ;; esac
# a draft without a sett: the default database, nothing cached
expect_ok synth_plain "$LOOM" synth "$W/basic-twill.wif" -o "$T/d.loomf" --quiet
case "$(db_of "$T/d.loomf")" in */default.ldb) pass no_sett_default ;;
	*) fail no_sett_default "$(db_of "$T/d.loomf")" ;; esac
# --db with another aspect: a warning naming both
expect_ok synth_db "$LOOM" synth "$W/sett-square.wif" --db "$LOOM_BUILD/share/loom/default.ldb" \
	-o "$T/e.loomf"
expect_err_contains db_mismatch_warning "default.ldb has crossings of 24x16 voxels (aspect 1.5) but the draft's sett 54.05 x 54.05 ends x picks per cm needs aspect 1"
expect_ok synth_db_match "$LOOM" synth "$W/sett-two-one.wif" --db "$(db_of "$T/c.loomf")" \
	-o "$T/f.loomf"
if grep -q "aspect" "$T/err"; then fail db_match_no_warning "$(cat "$T/err")"; else pass db_match_no_warning; fi
# the cache is bounded: at 5 MB only the newest database stays
touch -d '2 hours ago' "$T/cache"/sett-*.ldb
sed 's/^Spacing=5.25$/Spacing=6/' "$W/sett-two-one.wif" >"$T/other.wif"
LOOM_CACHE_MAX_MB=5 expect_ok synth_bounded2 "$LOOM" synth "$T/other.wif" -o "$T/h.loomf"
n=$(ls "$T/cache" | grep -c '^sett-.*\.ldb$')
if [ "$n" = 1 ]; then pass cache_bounded; else fail cache_bounded "$n files: $(ls -l "$T/cache")"; fi
expect_err_contains cache_bounded_msg "from the cache (over 5 MB)"
expect_exit bad_max 1 env LOOM_CACHE_MAX_MB=lots "$LOOM" synth "$W/sett-square.wif" -o "$T/i.loomf"
expect_err_contains bad_max_msg "LOOM_CACHE_MAX_MB=lots: expected a positive number"
# XDG_CACHE_HOME when LOOM_CACHE_DIR is unset
expect_ok synth_xdg env -u LOOM_CACHE_DIR XDG_CACHE_HOME="$T/xdg" "$LOOM" synth \
	"$W/sett-square.wif" -o "$T/j.loomf" --quiet
if ls "$T/xdg/loom"/sett-*.ldb >/dev/null 2>&1; then pass xdg_cache; else fail xdg_cache "nothing in $T/xdg/loom"; fi
# --fibre: the generated database's yarns (part of the key); for a draft
# that states no sett, the small preset's geometry with those yarns, the
# same bytes as `loom exemplar generate --preset small --min-crossings 10 --fibre ...`
hash_of() { # DB -> content hash
	"$LOOM" exemplar info "$1" --json | python3 -c \
		'import json,sys; print(json.load(sys.stdin)["content_hash"])'
}
expect_ok fibre_no_sett "$LOOM" synth "$W/basic-twill.wif" --fibre silk,wool -o "$T/k.loomf"
expect_err_contains fibre_no_sett_msg "yarns silk/wool: generated $T/cache/sett-"
expect_ok fibre_ref "$LOOM" exemplar generate --preset small --seed 1 --min-crossings 10 --fibre silk,wool \
	--quiet -o "$T/silkwool.ldb"
a=$(hash_of "$(db_of "$T/k.loomf")"); b=$(hash_of "$T/silkwool.ldb")
if [ "$a" = "$b" ]; then pass fibre_same_as_generate; else fail fibre_same_as_generate "$a vs $b"; fi
c=$(hash_of "$LOOM_BUILD/share/loom/default.ldb")
if [ "$a" != "$c" ]; then pass fibre_not_default; else fail fibre_not_default "$a"; fi
# the default yarns named: the same database as the built-in one, so that
# the Makefile's default.ldb recipe (seed, --min-crossings) and the
# generated databases' parameters (settdb.c) cannot drift apart
expect_ok fibre_cotton "$LOOM" synth "$W/basic-twill.wif" --fibre cotton -o "$T/k2.loomf" --quiet
a=$(hash_of "$(db_of "$T/k2.loomf")")
if [ "$a" = "$c" ]; then pass fibre_cotton_is_default; else fail fibre_cotton_is_default "$a vs $c"; fi
# on a draft with a sett: the sett's block, another key than cotton's
expect_ok fibre_sett "$LOOM" synth "$W/sett-square.wif" --fibre silk -o "$T/l.loomf" --quiet
p=$(db_of "$T/l.loomf")
case "$(block_of "$p")" in "16 16 "*) pass fibre_sett_block ;; *) fail fibre_sett_block "$(block_of "$p")" ;; esac
if [ "$p" != "$(db_of "$T/a.loomf")" ]; then pass fibre_sett_own_key; else fail fibre_sett_own_key "$p"; fi
expect_exit fibre_bad 2 "$LOOM" synth "$W/sett-square.wif" --fibre tweed -o "$T/m.loomf"
expect_err_contains fibre_bad_msg "--fibre: generator: warp fibre 'tweed' (expected none, cotton"
expect_exit fibre_with_db 2 "$LOOM" synth "$W/sett-square.wif" --fibre silk \
	--db "$LOOM_BUILD/share/loom/default.ldb" -o "$T/m.loomf"
expect_err_contains fibre_with_db_msg "--fibre chooses the yarns of a generated database; --db names one"
