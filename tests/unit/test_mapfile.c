/* tests/unit/test_mapfile.c - posterized image + mapping file -> design
   (paper 5.2) against hand-computed cases, and every mapping-file error. */
#include "check.h"
#include "loom.h"

#include <math.h>

/* An RGB image from rows of letters, each letter a colour from `pal`
   ('A' = pal[0], ...). */
static loom_image *rgb_image(const char *const *rows, const uint32_t *pal)
{
	loom_image *img = NULL;
	uint32_t h = 0, w = (uint32_t)strlen(rows[0]);

	while (rows[h])
		h++;
	if (loom_image_new(w, h, 3, &img))
		return NULL;
	for (uint32_t y = 0; y < h; y++)
		for (uint32_t x = 0; x < w; x++) {
			uint32_t c = pal[rows[y][x] - 'A'];
			uint8_t *p = img->pixels + 3 * ((size_t)y * w + x);
			p[0] = (uint8_t)(c >> 16);
			p[1] = (uint8_t)(c >> 8);
			p[2] = (uint8_t)c;
		}
	return img;
}

static int from_text(const loom_image *img, const char *text, loom_design **d,
                     loom_diag *dg)
{
	return loom_design_from_image(img, text, strlen(text), "m.map", d, dg);
}

static const uint32_t red_blue[] = {0xff0000, 0x0000ff, 0x00ff00};
static const char *const abba[] = {"AABB", "ABBA", "BBAA", NULL};

static void hand_computed(void)
{
	/* A = plain: W = 1 where i+j is even.  B = twill 2/2 (Z): W = 1 where
	   (i - j) mod 4 < 2.  Row 0: A A B B -> 1 0 0 1; row 1: A B B A ->
	   0 1 0 1; row 2: B B A A -> 0 1 1 0. */
	static const uint8_t weave[] = {1, 0, 0, 1, 0, 1, 0, 1, 0, 1, 1, 0};
	static const uint8_t warp[] = {0, 0, 1, 1, 0, 1, 1, 0, 1, 1, 0, 0};
	const char *map =
		"# two-colour Jacquard\n"
		"yarn red  #ff0000 alignment=0.2\n"
		"yarn blue 0,0,0.5   thickness=1.5  # inline comment\n"
		"yarn base #808080\n"
		"\n"
		"colour #ff0000 plain     warp=red  weft=base\n"
		"COLOR  #0000FF twill:2/2 weft=base warp=blue\n";
	loom_image *img = rgb_image(abba, red_blue);
	loom_design *d = NULL;
	loom_diag dg = {0};

	CHECK_EQ_INT(from_text(img, map, &d, &dg), LOOM_OK);
	if (!d) {
		printf("  %s\n", dg.message);
		loom_image_free(img);
		return;
	}
	CHECK_EQ_INT(d->rows, 3);
	CHECK_EQ_INT(d->cols, 4);
	CHECK(memcmp(d->weave, weave, 12) == 0);
	CHECK(memcmp(d->warp_type, warp, 12) == 0);
	for (int k = 0; k < 12; k++)
		CHECK_EQ_INT(d->weft_type[k], 2);
	CHECK_EQ_INT(d->n_types, 3);
	CHECK(strcmp(d->types[0].name, "red") == 0);
	CHECK(strcmp(d->types[1].name, "blue") == 0);
	CHECK(strcmp(d->types[2].name, "base") == 0);
	CHECK(d->types[0].albedo[0] == 1.0f && d->types[0].albedo[1] == 0.0f);
	CHECK(fabsf(d->types[0].alignment - 0.2f) < 1e-6f);
	CHECK(fabsf(d->types[1].albedo[2] - 0.5f) < 1e-6f);
	CHECK(fabsf(d->types[1].thickness - 1.5f) < 1e-6f);
	/* #xx80xx is sRGB 128/255: linear ((0.50196 + 0.055) / 1.055)^2.4 = 0.21586 */
	CHECK(fabsf(d->types[2].albedo[1] - 0.215861f) < 1e-5f);
	CHECK(fabsf(d->types[2].alignment - 0.3f) < 1e-6f); /* default */
	CHECK_EQ_INT(dg.n_warnings, 0);
	CHECK_EQ_INT(loom_design_validate(d, NULL), LOOM_OK);
	loom_design_free(d);
	loom_image_free(img);
}

/* Larger tiling: every cell equals its colour's weave at its own position. */
static void tiled_from_origin(void)
{
	loom_image *img;
	loom_design *d = NULL;
	loom_weave_params sat, tw;
	const char *map = "colour 0 satin:1/4\ncolour 255 twill:1/3:s\r\n";
	int ok = 1;

	CHECK_EQ_INT(loom_image_new(37, 23, 1, &img), LOOM_OK);
	for (uint32_t y = 0; y < 23; y++)
		for (uint32_t x = 0; x < 37; x++)
			img->pixels[y * 37 + x] = (x * x + 3 * y * y) % 97 < 40 ? 0 : 255;
	CHECK_EQ_INT(from_text(img, map, &d, NULL), LOOM_OK);
	CHECK_EQ_INT(loom_weave_parse("satin:1/4", &sat, NULL), LOOM_OK);
	CHECK_EQ_INT(loom_weave_parse("twill:1/3:s", &tw, NULL), LOOM_OK);
	for (uint32_t y = 0; d && y < 23; y++)
		for (uint32_t x = 0; x < 37; x++) {
			const loom_weave_params *p = img->pixels[y * 37 + x] ? &tw : &sat;
			ok &= loom_design_at(d, y, x) == loom_weave_cell(p, y, x);
			ok &= d->warp_type[y * 37 + x] == 0 && d->weft_type[y * 37 + x] == 1;
		}
	CHECK(ok);
	CHECK(d && d->n_types == 2 && strcmp(d->types[1].name, "weft") == 0);
	loom_design_free(d);
	loom_image_free(img);
}

static void palette_index(void)
{
	loom_image *img = rgb_image(abba, red_blue);
	loom_design *d = NULL;
	loom_diag dg = {0};

	img->n_palette = 3;
	img->palette = malloc(9);
	memcpy(img->palette, "\x00\x00\xff\xff\x00\x00\x00\xff\x00", 9);
	CHECK_EQ_INT(from_text(img, "colour index=1 plain\ncolour index=0 basket:2\n",
	                       &d, &dg), LOOM_OK);
	CHECK(d && d->weave[0] == 1 && d->weave[1] == 0); /* A = red = index 1 */
	loom_design_free(d);
	CHECK_EQ_INT(from_text(img, "colour index=3 plain\n", &d, &dg), LOOM_EFORMAT);
	CHECK_STR_CONTAINS(dg.message, "m.map:1: index=3 but the image palette is shorter");
	/* an unmapped colour names its palette index */
	CHECK_EQ_INT(from_text(img, "colour index=1 plain\n", &d, &dg), LOOM_EFORMAT);
	CHECK_STR_CONTAINS(dg.message, "m.map: image colour #0000ff (palette index 0) "
	                   "(first at pixel x=2, y=0) has no 'colour' line");
	loom_image_free(img);
}

static int n_warned;
static char warned[512];
static void on_warn(void *user, const char *msg)
{
	(void)user;
	n_warned++;
	snprintf(warned, sizeof warned, "%s", msg);
}

static void unused_colour_warns(void)
{
	loom_image *img = rgb_image(abba, red_blue);
	loom_design *d = NULL;
	loom_diag dg = {0};

	dg.warn = on_warn;
	CHECK_EQ_INT(from_text(img, "colour #ff0000 plain\ncolour #0000ff plain\n"
	                       "colour #123456 plain\n", &d, &dg), LOOM_OK);
	CHECK_EQ_INT(n_warned, 1);
	CHECK_STR_CONTAINS(warned, "m.map:3: colour #123456 does not occur in the image");
	loom_design_free(d);
	loom_image_free(img);
}

struct bad {
	const char *map;
	int code;
	const char *frag;
};

static void errors(void)
{
	static const struct bad cases[] = {
		{"bogus x\n", LOOM_EFORMAT, "m.map:1: expected 'yarn' or 'colour', got 'bogus'"},
		{"\n\nyarn\n", LOOM_EFORMAT, "m.map:3: expected 'yarn NAME ALBEDO [alignment=A] [thickness=T] [fibre=F]'"},
		{"yarn r@d #ff0000\n", LOOM_EFORMAT, "m.map:1: expected a yarn name (letters, digits, '_', '-', '.'; at most 31 characters), got 'r@d'"},
		{"yarn abcdefghijabcdefghijabcdefghijab #ff0000\n", LOOM_EFORMAT, "expected a yarn name"},
		{"yarn red #ff00\n", LOOM_EFORMAT, "m.map:1: expected an albedo #RRGGBB or r,g,b with each in 0..1, got '#ff00'"},
		{"yarn red 1,2,0\n", LOOM_EFORMAT, "got '1,2,0'"},
		{"yarn red 0.5,0.5\n", LOOM_EFORMAT, "got '0.5,0.5'"},
		{"yarn red 0.5,0.5,0.5,0.5\n", LOOM_EFORMAT, "got '0.5,0.5,0.5,0.5'"},
		{"yarn red #ff0000 alignment=0\n", LOOM_EFORMAT, "m.map:1: alignment must be a number in (0,1], got '0'"},
		{"yarn red #ff0000 thickness=-1\n", LOOM_EFORMAT, "thickness must be a number >= 0, got '-1'"},
		{"yarn red #ff0000 gloss=1\n", LOOM_EFORMAT, "m.map:1: expected alignment=A, thickness=T or fibre=F, got 'gloss=1'"},
		{"yarn a #000000\nyarn a #ffffff\n", LOOM_EFORMAT, "m.map:2: yarn 'a' is already defined on line 1"},
		{"colour #ff0000\n", LOOM_EFORMAT, "m.map:1: expected 'colour COLOUR WEAVE [warp=YARN] [weft=YARN]'"},
		{"colour red plain\n", LOOM_EFORMAT, "m.map:1: expected an image colour: #RRGGBB, a grey level 0..255 or index=K (K = 0..255), got 'red'"},
		{"colour 256 plain\n", LOOM_EFORMAT, "got '256'"},
		{"colour index=x plain\n", LOOM_EFORMAT, "got 'index=x'"},
		{"colour #ff0000 twill:2\n", LOOM_EINVAL, "m.map:1: weave 'twill:2': expected OVER/UNDER"},
		{"colour #ff0000 satin:1/5:move=3\n", LOOM_EINVAL, "m.map:1: satin 1/5: move 3 shares the factor 3"},
		{"colour #ff0000 plain warp=a warp=b\n", LOOM_EFORMAT, "m.map:1: warp= given twice"},
		{"colour #ff0000 plain wrap=a\n", LOOM_EFORMAT, "m.map:1: expected warp=YARN or weft=YARN, got 'wrap=a'"},
		{"colour #ff0000 plain weft=\n", LOOM_EFORMAT, "expected a yarn name"},
		{"yarn a #000000\ncolour #ff0000 plain warp=b weft=a\n", LOOM_EFORMAT, "m.map:2: unknown yarn 'b' for warp= (defined: a)"},
		{"yarn a #000000\ncolour #ff0000 plain warp=a\n", LOOM_EFORMAT, "m.map:2: unknown yarn 'weft' for weft= (defined: a)"},
		{"colour #ff0000 plain warp=red\n", LOOM_EFORMAT, "unknown yarn 'red' for warp= (defined: warp, weft)"},
		{"colour #ff0000 plain\ncolour #FF0000 twill:2/2\n", LOOM_EFORMAT, "m.map:2: colour #ff0000 is already mapped on line 1"},
		{"colour 0 plain\ncolour #000000 plain\n", LOOM_EFORMAT, "m.map:2: colour #000000 is already mapped on line 1"},
		{"colour #000000 plain\ncolour 0 plain\n", LOOM_EFORMAT, "m.map:2: colour grey level 0 is already mapped on line 1"},
		{"colour index=1 plain\n", LOOM_EFORMAT, "m.map:1: index=1 but the image has no palette (index=K needs an indexed PNG)"},
		{"", LOOM_EFORMAT, "m.map: no 'colour' lines"},
		{"# only a comment\nyarn a #000000\n", LOOM_EFORMAT, "no 'colour' lines"},
		{"colour \x01 plain\n", LOOM_EFORMAT, "m.map:1: unexpected control byte 0x01"},
		{"colour #ff0000 plain a b c d e f g h i j k l m n\n", LOOM_EFORMAT, "m.map:1: more than 16 fields on one line"},
		{"colour #ff0000 plain #x\n", LOOM_EFORMAT, "expected warp=YARN or weft=YARN, got '#x'"},
		{"colour #ff0000 plain\n", LOOM_EFORMAT, "m.map: image colour #0000ff (first at pixel x=2, y=0) has no 'colour' line"},
		{"colour #0000ff plain\n", LOOM_EFORMAT, "m.map: image colour #ff0000 (first at pixel x=0, y=0) has no 'colour' line"},
	};
	loom_image *img = rgb_image(abba, red_blue);

	for (size_t k = 0; k < sizeof cases / sizeof cases[0]; k++) {
		loom_design *d = (loom_design *)1;
		loom_diag dg = {0};
		int rc = from_text(img, cases[k].map, &d, &dg);
		if (rc != cases[k].code || !strstr(dg.message, cases[k].frag)) {
			printf("  case %zu: code %d, message \"%s\"; expected %d and \"%s\"\n",
			       k, rc, dg.message, cases[k].code, cases[k].frag);
			CHECK(0);
		}
		CHECK(d == NULL);
	}
	loom_image_free(img);
}

static void grey_unmapped_and_comments(void)
{
	loom_image *img;
	loom_design *d = NULL;
	loom_diag dg = {0};

	CHECK_EQ_INT(loom_image_new(3, 2, 1, &img), LOOM_OK);
	memcpy(img->pixels, "\x00\x00\x00\x00\x00\x07", 6);
	CHECK_EQ_INT(from_text(img, "colour 0 plain\n", &d, &dg), LOOM_EFORMAT);
	CHECK_STR_CONTAINS(dg.message, "m.map: image colour grey level 7 (first at pixel x=2, y=1) has no 'colour' line");
	/* '#' alone or at a line start is a comment; #RRGGBB is a colour */
	CHECK_EQ_INT(from_text(img, "  # comment\n#colour 9 plain\ncolour #000000 plain # c\n"
	                       "colour #070707 basket:2 #\n", &d, &dg), LOOM_OK);
	CHECK(d && d->weave[5] == loom_weave_cell(&(loom_weave_params){LOOM_WEAVE_BASKET, 2, 2, 0, 1, 0}, 1, 2));
	loom_design_free(d);
	loom_image_free(img);
}

static void too_many_colours(void)
{
	loom_image *img;
	loom_design *d = NULL;
	loom_diag dg = {0};

	CHECK_EQ_INT(loom_image_new(9, 8, 3, &img), LOOM_OK);
	for (int k = 0; k < 72; k++)
		img->pixels[3 * k] = (uint8_t)k; /* 72 distinct reds */
	CHECK_EQ_INT(from_text(img, "colour 0 plain\n", &d, &dg), LOOM_ERANGE);
	CHECK_STR_CONTAINS(dg.message, "m.map: the image has more than 64 colours (the 65th new one is at pixel x=1, y=7); posterize it");
	CHECK(d == NULL);
	/* exactly 64 colours is fine as far as counting goes */
	memset(img->pixels + 3 * 64, 0, 3 * 8);
	CHECK_EQ_INT(from_text(img, "colour 0 plain\n", &d, &dg), LOOM_EFORMAT);
	CHECK_STR_CONTAINS(dg.message, "image colour #010000 (first at pixel x=1, y=0)");
	loom_image_free(img);
}

static void bad_arguments(void)
{
	loom_image *img = rgb_image(abba, red_blue);
	loom_design *d = NULL;

	CHECK_EQ_INT(loom_design_from_image(NULL, "x", 1, "m", &d, NULL), LOOM_EINVAL);
	CHECK_EQ_INT(loom_design_from_image(img, NULL, 4, "m", &d, NULL), LOOM_EINVAL);
	CHECK_EQ_INT(loom_design_from_image(img, "x", 1, "m", NULL, NULL), LOOM_EINVAL);
	/* not NUL-terminated: only map_len bytes are read */
	CHECK_EQ_INT(loom_design_from_image(img, "colour #ff0000 plain\ncolour #0000ff plainXYZ",
	                                    41, NULL, &d, NULL), LOOM_OK);
	loom_design_free(d);
	loom_image_free(img);
}

int main(void)
{
	CHECK_MAIN_BEGIN("test_mapfile");
	RUN(hand_computed);
	RUN(tiled_from_origin);
	RUN(palette_index);
	RUN(unused_colour_warns);
	RUN(errors);
	RUN(grey_unmapped_and_comments);
	RUN(too_many_colours);
	RUN(bad_arguments);
	CHECK_MAIN_END();
}
