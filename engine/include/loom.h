/*
 * loom.h - the one public header of libloom.
 *
 * loom builds volumetric models of woven cloth from a fabric design and a
 * small database of volumetric exemplars (Zhao, Jakob, Marschner, Bala,
 * "Structure-aware Synthesis for Predictive Woven Fabric Appearance",
 * SIGGRAPH 2012).  See docs/api.md for one entry per function.
 *
 * Build against it with:  cc prog.c $(pkg-config --cflags --libs loom)
 */
#ifndef LOOM_H
#define LOOM_H

#include "loom/common.h"
#include "loom/design.h"
#include "loom/synth.h"
#include "loom/io.h"
#include "loom/db.h"
#include "loom/fabric.h"
#include "loom/texture.h"
#include "loom/volio.h"
#include "loom/scan.h"
#include "loom/render.h"
#include "loom/preview.h"
#include "loom/paint.h"

#endif /* LOOM_H */
