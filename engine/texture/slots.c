/*
 * engine/texture/slots.c - the per-thread state of the virtual texture:
 * thread slots, the thread-local bindings and the registry of open textures.
 *
 * THREADS
 *   Each calling thread is bound to a slot on its first call: a
 *   thread-local table of (texture serial, slot) bindings, most recent
 *   first, so the common case is one thread-local load and compare
 *   (slot_enter, inline in texture_impl.h).  Slots come from the texture's
 *   pool of max_threads; when it is empty the thread binds to the overflow
 *   slot, which every overflow thread uses under a mutex (and leaves as
 *   soon as a pool slot is free).  A slot goes back to the pool when its
 *   thread calls loom_texture_thread_done, evicts the binding (more than
 *   TL_BINDINGS textures in use), or exits (a pthread key destructor).
 *   Thread exit may race with close: both take the process-wide registry
 *   lock, and a binding is only followed to a texture found alive in the
 *   registry (same address and serial; serials are never reused).  The
 *   registry is the only process-wide state: a mutex, a list of open
 *   textures, a serial counter, one key.
 */
#include "texture_impl.h"

#include <stdio.h>
#include <stdlib.h>

static pthread_mutex_t g_lock = PTHREAD_MUTEX_INITIALIZER;
static loom_texture *g_live;       /* open textures */
static uint64_t g_serial;          /* last serial given (under g_lock) */
static pthread_once_t g_once = PTHREAD_ONCE_INIT;
static pthread_key_t g_key;
static int g_key_ok;

_Thread_local struct loom__binding loom__tl_bind[TL_BINDINGS];
static _Thread_local int tl_keyed;
static _Thread_local char tl_msg[LOOM_DIAG_MSG_MAX];

void loom__slot_return(loom_texture *t, struct tslot *s)
{
	if (s->shared)
		return;
	memo_drop(s);
	loom__cache_thread_flush(s->cth);
	pthread_mutex_lock(&t->pool_lock);
	s->next_free = t->free_head;
	t->free_head = (uint32_t)(((uint8_t *)s - (uint8_t *)slot_at(t, 0)) / t->slot_bytes);
	atomic_fetch_add(&t->n_free, 1);
	pthread_mutex_unlock(&t->pool_lock);
}

/* Drop binding b, returning its slot if its texture is still open. */
static void unbind(struct loom__binding *b)
{
	if (b->serial) {
		pthread_mutex_lock(&g_lock);
		for (loom_texture *p = g_live; p; p = p->live_next)
			if (p == b->tex && p->serial == b->serial) {
				loom__slot_return(p, b->slot); /* no-op for the overflow slot */
				break;
			}
		pthread_mutex_unlock(&g_lock);
	}
	memset(b, 0, sizeof *b);
}

static void thread_exit(void *unused)
{
	(void)unused;
	for (int k = 0; k < TL_BINDINGS; k++)
		unbind(&loom__tl_bind[k]);
}

static void make_key(void)
{
	g_key_ok = pthread_key_create(&g_key, thread_exit) == 0;
}

struct tslot *loom__pool_take(loom_texture *t)
{
	struct tslot *s = NULL;

	pthread_mutex_lock(&t->pool_lock);
	if (t->free_head != t->n_slots) {
		s = slot_at(t, t->free_head);
		t->free_head = s->next_free;
		atomic_fetch_sub(&t->n_free, 1);
	}
	pthread_mutex_unlock(&t->pool_lock);
	return s;
}

struct tslot *loom__slot_bind(loom_texture *t)
{
	struct loom__binding b;
	int k;

	for (k = 1; k < TL_BINDINGS; k++)
		if (loom__tl_bind[k].serial == t->serial)
			break;
	if (k < TL_BINDINGS) {
		b = loom__tl_bind[k];
		memmove(&loom__tl_bind[1], &loom__tl_bind[0], (size_t)k * sizeof b);
		loom__tl_bind[0] = b;
		return b.slot;
	}
	if (!tl_keyed) {
		pthread_once(&g_once, make_key);
		/* without the key a slot is not returned at thread exit (it stays
		   bound until close): still correct */
		if (g_key_ok && pthread_setspecific(g_key, &tl_keyed) == 0)
			tl_keyed = 1;
	}
	b.serial = t->serial;
	b.tex = t;
	b.slot = loom__pool_take(t);
	if (!b.slot)
		b.slot = slot_at(t, t->n_slots - 1);
	if (loom__tl_bind[TL_BINDINGS - 1].serial)
		unbind(&loom__tl_bind[TL_BINDINGS - 1]);
	memmove(&loom__tl_bind[1], &loom__tl_bind[0], (TL_BINDINGS - 1) * sizeof b);
	loom__tl_bind[0] = b;
	return b.slot;
}

int loom__slot_error(loom_texture *t, struct tslot *s, int rc, const char *msg)
{
	snprintf(s->msg, sizeof s->msg, "%s", msg);
	pthread_mutex_lock(&t->msg_lock);
	snprintf(t->msg, sizeof t->msg, "%s", msg);
	pthread_mutex_unlock(&t->msg_lock);
	bump(&s->cnt.errors, 1);
	return rc;
}

void loom__registry_add(loom_texture *t)
{
	pthread_mutex_lock(&g_lock);
	t->serial = ++g_serial;
	t->live_next = g_live;
	g_live = t;
	pthread_mutex_unlock(&g_lock);
}

void loom__registry_remove(loom_texture *t)
{
	pthread_mutex_lock(&g_lock);
	for (loom_texture **pp = &g_live; *pp; pp = &(*pp)->live_next)
		if (*pp == t) {
			*pp = t->live_next;
			break;
		}
	pthread_mutex_unlock(&g_lock);
	/* bindings left in threads' tables no longer match a live texture */
	if (loom__tl_bind[0].serial == t->serial)
		memset(&loom__tl_bind[0], 0, sizeof loom__tl_bind[0]);
}

LOOM_API void loom_texture_thread_done(loom_texture *t)
{
	int k;

	if (!t)
		return;
	for (k = 0; k < TL_BINDINGS; k++)
		if (loom__tl_bind[k].serial == t->serial)
			break;
	if (k == TL_BINDINGS)
		return;
	loom__slot_return(t, loom__tl_bind[k].slot);
	memmove(&loom__tl_bind[k], &loom__tl_bind[k + 1],
	        (size_t)(TL_BINDINGS - 1 - k) * sizeof loom__tl_bind[0]);
	memset(&loom__tl_bind[TL_BINDINGS - 1], 0, sizeof loom__tl_bind[0]);
}

LOOM_API const char *loom_texture_errmsg(const loom_texture *ct)
{
	loom_texture *t = (loom_texture *)ct; /* locks are not part of the value */
	int k;

	if (!t) {
		snprintf(tl_msg, sizeof tl_msg, "loom_texture_errmsg: NULL texture");
		return tl_msg;
	}
	for (k = 0; k < TL_BINDINGS; k++)
		if (loom__tl_bind[k].serial == t->serial)
			break;
	if (k < TL_BINDINGS && loom__tl_bind[k].slot->shared) {
		pthread_mutex_lock(&t->overflow_lock);
		snprintf(tl_msg, sizeof tl_msg, "%s", loom__tl_bind[k].slot->msg);
		pthread_mutex_unlock(&t->overflow_lock);
	} else if (k < TL_BINDINGS) {
		snprintf(tl_msg, sizeof tl_msg, "%s", loom__tl_bind[k].slot->msg);
	} else {
		tl_msg[0] = 0;
	}
	return tl_msg;
}
