/* tools/loom/commands.h - the subcommands of `loom`; one file each. */
#ifndef LOOM_COMMANDS_H
#define LOOM_COMMANDS_H

int cmd_pattern(int argc, char **argv);  /* cmd_pattern.c */
int cmd_demo(int argc, char **argv);     /* cmd_demo.c */
int cmd_exemplar(int argc, char **argv); /* cmd_exemplar.c */
int cmd_synth(int argc, char **argv);    /* cmd_synth.c */
int cmd_info(int argc, char **argv);     /* cmd_info.c */
int cmd_sample(int argc, char **argv);   /* cmd_sample.c */
int cmd_export(int argc, char **argv);   /* cmd_export.c */
int cmd_scan(int argc, char **argv);     /* cmd_scan.c */
int cmd_preview(int argc, char **argv);  /* cmd_preview.c */
int cmd_render(int argc, char **argv);   /* cmd_render.c */
int cmd_look(int argc, char **argv);     /* cmd_look.c */
int cmd_serve(int argc, char **argv);    /* cmd_serve.c */
int cmd_paint(int argc, char **argv);    /* cmd_paint.c */
int cmd_compare(int argc, char **argv);  /* cmd_compare.c */


/* Read DESIGN (WIF, weave image, or a posterized image with map) and the
   optional type maps; exits with a message on failure (cmd_synth.c). */
struct loom_design;
struct loom_diag;
struct loom_design *synth_load_design(const char *prog, const char *in,
                                      const char *map, const char *warp,
                                      const char *weft, struct loom_diag *diag);

#endif
