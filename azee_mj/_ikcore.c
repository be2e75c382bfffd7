/* The posture solver's compiled core as a Python module (see azee_mj/posture/plan.py).

   A Core holds one problem compiled by posture.Plan: its row blocks, the free dofs, the
   per-body-pair contact floor and the geom pairs that can collide. It evaluates the scaled
   residual rows and their Jacobian over the free dofs (constraint rows, then one row per
   contact deeper than its pair's floor), runs one Levenberg-Marquardt run whose steps are
   box-constrained QPs (mju_boxQP) and the polish toward the most natural posture; each run
   says why it stopped. Constraints of a form the core does not know are written by a Python
   callback. The records Python passes (Block, Term, Tunables) are laid out in _ikcore_shared.h;
   `layout()` reports their sizes and offsets.

   Only the buffer protocol is used (no numpy headers): arrays come in as contiguous buffers
   of the expected item size, results go out as bytes. Units: metres, radians. */
#include <stddef.h>

#include "_ikcore_shared.h"

static const char* STOP_NAMES[STOP_COUNT] = {
    "DONE", "MET_SLOW", "STALL", "GUIDE_STALL", "DAMPING", "NO_STEP", "MAX_ITER",
    "NO_FREEDOM", "POLISHED"};

/* A contiguous buffer of n items of itemsize bytes (n < 0: any count). Returns 0, or -1 with
   a Python error set (v released). */
static int get_buf(PyObject* o, Py_buffer* v, Py_ssize_t itemsize, Py_ssize_t n, const char* what,
                   int writable) {
  if (PyObject_GetBuffer(o, v, PyBUF_C_CONTIGUOUS | PyBUF_FORMAT | (writable ? PyBUF_WRITABLE : 0)))
    return -1;
  if (v->itemsize != itemsize || (n >= 0 && v->len != n * itemsize)) {
    PyErr_Format(PyExc_ValueError, "%s: expected %zd items of %zd bytes, got %zd bytes", what, n,
                 itemsize, v->len);
    PyBuffer_Release(v);
    v->obj = NULL;
    return -1;
  }
  return 0;
}

static void release(Py_buffer* v) {
  if (v->obj) PyBuffer_Release(v);
  v->obj = NULL;
}

/* A copy of n bytes (at least one allocated), or NULL out of memory. */
static void* copy_of(const void* src, size_t n) {
  void* p = malloc(n ? n : 1);
  if (p && n) memcpy(p, src, n);
  return p;
}

static void free_natural(Core* s) {
  free(s->edof), free(s->escale), free(s->comfort), free(s->neutral), free(s->anc);
  s->edof = NULL, s->escale = s->comfort = s->neutral = NULL, s->anc = NULL;
}

/* The Python objects a Core holds (the owner, the callbacks: bound methods of the Plan that
   holds the Core, a reference cycle) are visible to the cyclic garbage collector, so a Plan
   is freed once unused instead of living as long as the process. */
static int Core_traverse(Core* s, visitproc visit, void* arg) {
  Py_VISIT(s->owner);
  Py_VISIT(s->callback);
  Py_VISIT(s->pref_cb);
  return 0;
}

static int Core_clear(Core* s) {
  Py_CLEAR(s->callback);
  Py_CLEAR(s->pref_cb);
  return 0;
}

static void Core_dealloc(Core* s) {
  PyObject_GC_UnTrack(s);
  release(&s->rbuf);
  release(&s->Jbuf);
  release(&s->prbuf);
  release(&s->pJbuf);
  Py_XDECREF(s->owner);
  Py_XDECREF(s->callback);
  Py_XDECREF(s->pref_cb);
  free(s->blocks), free(s->terms), free(s->inv), free(s->free), free(s->floor);
  free(s->pair), free(s->gclu), free(s->run), free(s->ccen), free(s->crad), free(s->hard);
  free_natural(s);
  free(s->tmp), free(s->tmp2), free(s->j1), free(s->j2);
  for (int b = 0; b < 2; b++) free(s->r[b]), free(s->J[b]), free(s->norms[b]);
  Py_TYPE(s)->tp_free((PyObject*)s);
}

/* The geom pairs (checked: in range, in type order, with a collision function). */
static int copy_pairs(Core* s, const Py_buffer* pb) {
  const mjModel* m = s->m;
  const int32_t* P = pb->buf;
  s->npair = (int)(pb->len / 8);
  if (!(s->pair = copy_of(P, pb->len))) return PyErr_NoMemory(), -1;
  for (int p = 0; p < s->npair; p++) {
    int g1 = P[2 * p], g2 = P[2 * p + 1];
    if (g1 < 0 || g2 < 0 || g1 >= m->ngeom || g2 >= m->ngeom ||
        m->geom_type[g1] > m->geom_type[g2] ||
        !mjCOLLISIONFUNC[m->geom_type[g1]][m->geom_type[g2]]) {
      PyErr_Format(PyExc_ValueError, "pairs: (%d, %d) is no geom pair in type order", g1, g2);
      return -1;
    }
  }
  return 0;
}

/* The geoms' clusters, and the pairs' runs of one cluster pair. */
static int copy_clusters(Core* s, const Py_buffer* cb) {
  int ngeom = s->m->ngeom;
  if (!(s->gclu = copy_of(cb->buf, cb->len))) return PyErr_NoMemory(), -1;
  s->nclu = 0;
  for (int g = 0; g < ngeom; g++)
    if (s->gclu[g] >= s->nclu) s->nclu = s->gclu[g] + 1;
  if (!(s->run = malloc(sizeof(int) * (s->npair + 1)))) return PyErr_NoMemory(), -1;
  s->nrun = 0;
  for (int p = 0; p < s->npair; p++) {
    int c1 = s->gclu[s->pair[2 * p]], c2 = s->gclu[s->pair[2 * p + 1]];
    if (c1 < 0 || c2 < 0) {
      PyErr_Format(PyExc_ValueError, "clusters: pair %d has a geom without a cluster", p);
      return -1;
    }
    if (!p || c1 != s->gclu[s->pair[2 * p - 2]] || c2 != s->gclu[s->pair[2 * p - 1]])
      s->run[s->nrun++] = p;
  }
  s->run[s->nrun] = s->npair;
  s->ccen = malloc(sizeof(double) * 3 * (s->nclu + 1));
  s->crad = malloc(sizeof(double) * (s->nclu + 1));
  return s->ccen && s->crad ? 0 : (PyErr_NoMemory(), -1);
}

/* The evaluation buffers. */
static int alloc_work(Core* s) {
  size_t n3 = sizeof(double) * 3 * s->nv;
  s->tmp = malloc(n3), s->tmp2 = malloc(n3), s->j1 = malloc(n3), s->j2 = malloc(n3);
  if (!s->tmp || !s->tmp2 || !s->j1 || !s->j2) return PyErr_NoMemory(), -1;
  for (int b = 0; b < 2; b++)
    if (!(s->norms[b] = calloc(s->nhard + 1, sizeof(double)))) return PyErr_NoMemory(), -1;
  if (grow(s, s->nrows + 64)) return PyErr_NoMemory(), -1;
  return 0;
}

/* Copies the buffers (B: blocks, terms, tunables, inv, free, floor, hard, pairs, clusters). */
static int core_copy(Core* s, Py_buffer* B) {
  s->nblock = (int)(B[0].len / sizeof(Block));
  s->nterm = (int)(B[1].len / sizeof(Term));
  memcpy(&s->tun, B[2].buf, sizeof(Tunables));
  s->nrows = (int)(B[3].len / 8);
  s->nfree = (int)(B[4].len / 4);
  if (B[6].len % 32) return PyErr_SetString(PyExc_ValueError, "hard: records of 4 f64"), -1;
  s->nhard = (int)(B[6].len / 32);
  s->blocks = copy_of(B[0].buf, B[0].len), s->terms = copy_of(B[1].buf, B[1].len);
  s->inv = copy_of(B[3].buf, B[3].len), s->free = copy_of(B[4].buf, B[4].len);
  s->floor = copy_of(B[5].buf, B[5].len), s->hard = copy_of(B[6].buf, B[6].len);
  if (!s->blocks || !s->terms || !s->inv || !s->free || !s->floor || !s->hard)
    return PyErr_NoMemory(), -1;
  for (int h = 0; h < s->nhard; h++) {
    const double* H = s->hard + 4 * h;
    int kind = (int)H[2] & ~HARD_RANGE; /* a range is an orientation's */
    if (!(H[0] >= 0 && H[0] <= H[1] && H[1] <= s->nrows && H[2] >= HARD_LINEAR &&
          kind <= HARD_SINE && (kind || H[2] == HARD_LINEAR) && H[3] > 0)) {
      PyErr_Format(PyExc_ValueError, "hard: record %d is no (first, end, kind, tol)", h);
      return -1;
    }
  }
  for (int b = 0; b < s->nblock; b++)
    if (s->blocks[b].kind == B_GENERIC) s->has_generic = 1;
  if (copy_pairs(s, B + 7) || copy_clusters(s, B + 8)) return -1;
  return alloc_work(s);
}

/* Core(model_addr, data_addr, owner, blocks (Block records), terms (Term records), tunables
        (one Tunables record), inv (nrows f64), free (int32), floor (nbody*nbody f64),
        r (nrows f64, writable), J (nrows*nv f64, writable), callback, hard (nhard*4 f64: first row, end row, kind, tol),
        pairs (npair*2 int32: the geom pairs to collide, in order), clusters (ngeom int32:
        each geom's cluster, -1 for none)) */
static int Core_init(Core* s, PyObject* args, PyObject* kw) {
  (void)kw;
  unsigned long long ma, da;
  PyObject *owner, *cb, *o[9], *orr, *oJ;
  if (s->m) return PyErr_SetString(PyExc_RuntimeError, "Core: initialised already"), -1;
  if (!PyArg_ParseTuple(args, "KKOOOOOOOOOOOOO", &ma, &da, &owner, o, o + 1, o + 2, o + 3,
                        o + 4, o + 5, &orr, &oJ, &cb, o + 6, o + 7, o + 8))
    return -1;
  s->m = (mjModel*)(uintptr_t)ma;
  s->d = (mjData*)(uintptr_t)da;
  Py_INCREF(owner), s->owner = owner;
  Py_INCREF(cb), s->callback = cb;
  s->nv = s->m->nv;
  s->nbody = s->m->nbody;
  static const char* what[9] = {"blocks", "terms", "tunables", "inv",     "free",
                                "floor",  "hard",  "pairs",    "clusters"};
  Py_ssize_t size[9] = {sizeof(Block), sizeof(Term), sizeof(Tunables), 8, 4, 8, 8, 4, 4};
  Py_ssize_t count[9] = {-1, -1, 1, -1, -1, (Py_ssize_t)s->nbody * s->nbody, -1, -1,
                         s->m->ngeom};
  Py_buffer B[9] = {{0}};
  int err = -1;
  for (int i = 0; i < 9; i++)
    if (get_buf(o[i], B + i, size[i], count[i], what[i], 0)) goto cleanup;
  if (core_copy(s, B)) goto cleanup;
  if (get_buf(orr, &s->rbuf, 8, s->nrows, "r", 1)) goto cleanup;
  if (get_buf(oJ, &s->Jbuf, 8, (Py_ssize_t)s->nrows * s->nv, "J", 1)) goto cleanup;
  err = 0;
cleanup:
  for (int i = 0; i < 9; i++) release(B + i);
  return err;
}

static PyObject* as_bytes(const double* x, Py_ssize_t n) {
  return PyBytes_FromStringAndSize((const char*)x, n * (Py_ssize_t)sizeof(double));
}

static PyObject* as_list(const double* x, int n) {
  PyObject* out = PyList_New(n);
  if (!out) return NULL;
  for (int i = 0; i < n; i++) {
    PyObject* v = PyFloat_FromDouble(x[i]);
    if (!v) return Py_DECREF(out), NULL;
    PyList_SET_ITEM(out, i, v);
  }
  return out;
}

/* rows(): the raw rows of the known blocks (and the callback's) on the posture in data. */
static PyObject* Core_rows(Core* s, PyObject* noargs) {
  (void)noargs;
  if (raw_rows(s)) return NULL;
  Py_RETURN_NONE;
}

/* evaluate(q, collide) -> (r bytes, J bytes (rows, nfree), norms bytes, depth) */
static PyObject* Core_evaluate(Core* s, PyObject* args) {
  PyObject* oq;
  int collide;
  if (!PyArg_ParseTuple(args, "Op", &oq, &collide)) return NULL;
  Py_buffer q;
  if (get_buf(oq, &q, 8, s->m->nq, "q", 0)) return NULL;
  int err = evaluate(s, q.buf, collide, 0);
  PyBuffer_Release(&q);
  if (err) return NULL;
  int k = s->rows[0];
  return Py_BuildValue("(NNNd)", as_bytes(s->r[0], k), as_bytes(s->J[0], (Py_ssize_t)k * s->nfree),
                       as_bytes(s->norms[0], s->nhard), s->depth[0]);
}

/* deepest(pairs) -> depth [m]: the deepest penetration (>= 0) on the posture in data among
   geom pairs (npair*2 int32, each in the type order of its function) outside the body pairs
   this problem lets touch (those with a floor). */
static PyObject* Core_deepest(Core* s, PyObject* args) {
  PyObject* op;
  if (!PyArg_ParseTuple(args, "O", &op)) return NULL;
  Py_buffer pb;
  if (get_buf(op, &pb, 4, -1, "pairs", 0)) return NULL;
  double depth = deepest(s, pb.buf, (int)(pb.len / 8));
  PyBuffer_Release(&pb);
  return PyFloat_FromDouble(depth);
}

/* The run's result: (q bytes, cost, it, history list, stop) plus, for lm, done and met. */
static PyObject* run_result(const double* q, int nq, const RunOut* o, int lm) {
  PyObject* hist = as_list(o->hist, o->nhist);
  if (!hist) return NULL;
  if (lm)
    return Py_BuildValue("(NdiiiNi)", as_bytes(q, nq), o->cost, o->done, o->it, o->met, hist,
                         (int)o->stop);
  return Py_BuildValue("(NdiNi)", as_bytes(q, nq), o->cost, o->it, hist, (int)o->stop);
}

/* A run's inputs: buffers B[0..nb) from o (B[0] the posture q, nq doubles), a copy of q for
   the run to move and room in r for nhist history entries. Returns the copy, or NULL with a
   Python error set; run_end then frees what was taken. */
static double* run_start(PyObject* const* o, Py_buffer* B, int nb, const char* const* what,
                         const Py_ssize_t* size, const Py_ssize_t* count, int nhist, RunOut* r) {
  for (int i = 0; i < nb; i++)
    if (get_buf(o[i], B + i, size[i], count[i], what[i], 0)) return NULL;
  double* q = copy_of(B[0].buf, B[0].len);
  r->hist = malloc(sizeof(double) * (nhist > 0 ? nhist : 1));
  if (!q || !r->hist) {
    free(q);
    PyErr_NoMemory();
    return NULL;
  }
  return q;
}

static PyObject* run_end(PyObject* out, double* q, RunOut* r, Py_buffer* B, int nb) {
  free(q);
  free(r->hist);
  for (int i = 0; i < nb; i++) release(B + i);
  return out;
}

/* lm(q, lo, hi, w, nat, posture, stop, max_iter, collide, early=True)
     -> (q bytes, cost, done, iterations, met, history list, stop)
   One Levenberg-Marquardt run; see lm_run and Solver._lm. */
static PyObject* Core_lm(Core* s, PyObject* args) {
  PyObject *o[5], *out = NULL;
  LMArgs a = {.early = 1};
  if (!PyArg_ParseTuple(args, "OOOOOddip|p", o, o + 1, o + 2, o + 3, o + 4, &a.posture, &a.stop,
                        &a.max_iter, &a.collide, &a.early))
    return NULL;
  int n = s->nfree, nq = s->m->nq;
  static const char* const what[5] = {"q", "lo", "hi", "w", "nat"};
  Py_ssize_t size[5] = {8, 8, 8, 8, 8}, count[5] = {nq, n, n, n, n};
  Py_buffer B[5] = {{0}};
  RunOut r = {0};
  double* q = run_start(o, B, 5, what, size, count, a.max_iter, &r);
  if (q) {
    a.lo = B[1].buf, a.hi = B[2].buf, a.w = B[3].buf, a.nat = B[4].buf;
    if (!lm_run(s, &a, q, &r)) out = run_result(q, nq, &r, 1);
  }
  return run_end(out, q, &r, B, 5);
}

/* polish(q, lo, hi, mov (int32, indices into free), stop, collide)
     -> (q bytes, natural cost, iterations, history list, stop)
   The most natural posture among those that meet the constraints; see Solver._polish. */
static PyObject* Core_polish(Core* s, PyObject* args) {
  PyObject *o[4], *out = NULL;
  PolishArgs a = {0};
  if (!PyArg_ParseTuple(args, "OOOOdp", o, o + 1, o + 2, o + 3, &a.stop, &a.collide)) return NULL;
  int n = s->nfree, nq = s->m->nq;
  static const char* const what[4] = {"q", "lo", "hi", "mov"};
  Py_ssize_t size[4] = {8, 8, 8, 4}, count[4] = {nq, n, n, -1};
  Py_buffer B[4] = {{0}};
  RunOut r = {0};
  double* q = run_start(o, B, 4, what, size, count, s->tun.natural_iter, &r);
  if (q) {
    a.lo = B[1].buf, a.hi = B[2].buf, a.mov = B[3].buf, a.nm = (int)(B[3].len / 4);
    if (!polish_run(s, &a, q, &r)) out = run_result(q, nq, &r, 0);
  }
  return run_end(out, q, &r, B, 4);
}

/* set_natural(edof int32, escale f64, comfort (nv) f64, neutral (nv) f64, anc (nv*nv) uint8,
               pref_r (npref) f64, pref_J (npref*nv) f64, pref_callback or None) */
static PyObject* Core_set_natural(Core* s, PyObject* args) {
  PyObject *o[5], *opr, *opJ, *cb, *out = NULL;
  if (!PyArg_ParseTuple(args, "OOOOOOOO", o, o + 1, o + 2, o + 3, o + 4, &opr, &opJ, &cb))
    return NULL;
  int nv = s->nv;
  static const char* what[5] = {"edof", "escale", "comfort", "neutral", "anc"};
  Py_ssize_t size[5] = {4, 8, 8, 8, 1}, count[5] = {-1, -1, nv, nv, (Py_ssize_t)nv * nv};
  Py_buffer B[5] = {{0}};
  for (int i = 0; i < 5; i++) {
    if (i == 1) count[1] = B[0].len / 4;
    if (get_buf(o[i], B + i, size[i], count[i], what[i], 0)) goto cleanup;
  }
  free_natural(s);
  s->ne = 0;
  s->edof = copy_of(B[0].buf, B[0].len), s->escale = copy_of(B[1].buf, B[1].len);
  s->comfort = copy_of(B[2].buf, B[2].len), s->neutral = copy_of(B[3].buf, B[3].len);
  s->anc = copy_of(B[4].buf, B[4].len);
  if (!s->edof || !s->escale || !s->comfort || !s->neutral || !s->anc) {
    PyErr_NoMemory();
    goto cleanup;
  }
  s->ne = (int)(B[0].len / 4);
  release(&s->prbuf);
  release(&s->pJbuf);
  s->npref = 0;
  if (get_buf(opr, &s->prbuf, 8, -1, "pref_r", 1)) goto cleanup;
  if (get_buf(opJ, &s->pJbuf, 8, (s->prbuf.len / 8) * nv, "pref_J", 1)) goto cleanup;
  s->npref = (int)(s->prbuf.len / 8);
  Py_XDECREF(s->pref_cb);
  Py_INCREF(cb);
  s->pref_cb = cb;
  out = Py_None;
  Py_INCREF(out);
cleanup:
  for (int i = 0; i < 5; i++) release(B + i);
  return out;
}

/* natural() -> (r bytes, J bytes (rows, nfree)): the naturalness rows on the posture in
   data (after mj_kinematics and mj_comPos). */
static PyObject* Core_natural(Core* s, PyObject* noargs) {
  (void)noargs;
  int nrn = s->ne + s->nfree + s->npref;
  double* r = malloc(sizeof(double) * (nrn + 1));
  double* J = malloc(sizeof(double) * (nrn + 1) * (s->nfree + 1));
  PyObject* out = NULL;
  if (!r || !J)
    PyErr_NoMemory();
  else if (natural_rows(s, r, J) >= 0)
    out = Py_BuildValue("(NN)", as_bytes(r, nrn), as_bytes(J, (Py_ssize_t)nrn * s->nfree));
  free(r);
  free(J);
  return out;
}

/* effort(model_addr, data_addr, edof int32, anc uint8 (nv*nv), cols int32)
     -> (tau bytes (ne,), J bytes (ne, ncols)) */
static PyObject* mod_effort(PyObject* self, PyObject* args) {
  (void)self;
  unsigned long long ma, da;
  PyObject *o[3], *out = NULL;
  if (!PyArg_ParseTuple(args, "KKOOO", &ma, &da, o, o + 1, o + 2)) return NULL;
  const mjModel* m = (const mjModel*)(uintptr_t)ma;
  const mjData* d = (const mjData*)(uintptr_t)da;
  static const char* what[3] = {"edof", "anc", "cols"};
  Py_ssize_t size[3] = {4, 1, 4}, count[3] = {-1, (Py_ssize_t)m->nv * m->nv, -1};
  Py_buffer B[3] = {{0}};
  double *tau = NULL, *J = NULL;
  for (int i = 0; i < 3; i++)
    if (get_buf(o[i], B + i, size[i], count[i], what[i], 0)) goto cleanup;
  int ne = (int)(B[0].len / 4), nc = (int)(B[2].len / 4);
  tau = malloc(sizeof(double) * (ne + 1));
  J = malloc(sizeof(double) * (ne + 1) * (nc + 1));
  if (!tau || !J) {
    PyErr_NoMemory();
    goto cleanup;
  }
  effort(m, d, ne, B[0].buf, B[1].buf, nc, B[2].buf, tau, J);
  out = Py_BuildValue("(NN)", as_bytes(tau, ne), as_bytes(J, (Py_ssize_t)ne * nc));
cleanup:
  free(tau);
  free(J);
  for (int i = 0; i < 3; i++) release(B + i);
  return out;
}

/* depth(model_addr, data_addr, allowed int32 (n, 2)) -> depth [m]: mj_collision on the
   posture in data (its kinematics run), then the deepest penetration (>= 0) but between the
   body pairs allowed (both orders listed). */
static PyObject* mod_depth(PyObject* self, PyObject* args) {
  (void)self;
  unsigned long long ma, da;
  PyObject* o;
  if (!PyArg_ParseTuple(args, "KKO", &ma, &da, &o)) return NULL;
  const mjModel* m = (const mjModel*)(uintptr_t)ma;
  mjData* d = (mjData*)(uintptr_t)da;
  Py_buffer B = {0};
  if (get_buf(o, &B, 4, -1, "allowed", 0)) return NULL;
  mj_collision(m, d);
  double depth = contact_depth(m, d, B.buf, (int)(B.len / 8));
  release(&B);
  return PyFloat_FromDouble(depth);
}

/* Whether a buffer of geom pairs (int32 (n, 2)) is ragged or names a geom the model lacks. */
static int bad_pairs(const mjModel* m, const Py_buffer* P) {
  const int32_t* g = P->buf;
  int n = (int)(P->len / 8), bad = P->len % 8 != 0;
  for (int i = 0; i < 2 * n && !bad; i++) bad = g[i] < 0 || g[i] >= m->ngeom;
  return bad;
}

/* pairs_depth(model_addr, data_addr, pairs int32 (n, 2), allowed int32 (k, 2)) -> depth [m]:
   MuJoCo's narrowphase on the geom pairs alone (no mj_collision) on the posture in data (its
   kinematics run), the deepest penetration (>= 0) but between the body pairs allowed. */
static PyObject* mod_pairs_depth(PyObject* self, PyObject* args) {
  (void)self;
  unsigned long long ma, da;
  PyObject *op, *oa;
  if (!PyArg_ParseTuple(args, "KKOO", &ma, &da, &op, &oa)) return NULL;
  const mjModel* m = (const mjModel*)(uintptr_t)ma;
  mjData* d = (mjData*)(uintptr_t)da;
  Py_buffer P = {0}, B = {0};
  if (get_buf(op, &P, 4, -1, "pairs", 0)) return NULL;
  if (get_buf(oa, &B, 4, -1, "allowed", 0)) return release(&P), NULL;
  const int32_t* g = P.buf;
  int n = (int)(P.len / 8), bad = bad_pairs(m, &P);
  double depth = bad ? 0.0 : pairs_depth(m, d, g, n, B.buf, (int)(B.len / 8));
  release(&P);
  release(&B);
  if (bad) return PyErr_SetString(PyExc_ValueError, "pairs: geom ids out of range"), NULL;
  return PyFloat_FromDouble(depth);
}

/* pairs_depths(model_addr, data_addr, qpos float64 (n, nq), pairs int32 (p, 2), allowed int32
   (k, 2)) -> bytes of n doubles: pairs_depth at each posture, its kinematics run (a run of
   frames in one call); data holds the last posture afterwards. */
static PyObject* mod_pairs_depths(PyObject* self, PyObject* args) {
  (void)self;
  unsigned long long ma, da;
  PyObject *oq, *op, *oa, *out = NULL;
  if (!PyArg_ParseTuple(args, "KKOOO", &ma, &da, &oq, &op, &oa)) return NULL;
  const mjModel* m = (const mjModel*)(uintptr_t)ma;
  mjData* d = (mjData*)(uintptr_t)da;
  Py_buffer Q = {0}, P = {0}, B = {0};
  if (get_buf(oq, &Q, 8, -1, "qpos", 0)) return NULL;
  if (get_buf(op, &P, 4, -1, "pairs", 0)) return release(&Q), NULL;
  if (get_buf(oa, &B, 4, -1, "allowed", 0)) return release(&Q), release(&P), NULL;
  const int32_t* g = P.buf;
  int np = (int)(P.len / 8), bad = bad_pairs(m, &P) || (Q.len / 8) % m->nq != 0;
  Py_ssize_t n = (Py_ssize_t)(Q.len / 8 / m->nq);
  double* depth = bad ? NULL : malloc(sizeof(double) * (size_t)(n ? n : 1));
  if (bad) {
    PyErr_SetString(PyExc_ValueError, "qpos: rows of nq values; pairs: geom ids in range");
  } else if (!depth) {
    PyErr_NoMemory();
  } else {
    const double* q = Q.buf;
    for (Py_ssize_t i = 0; i < n; i++) {
      mju_copy(d->qpos, q + i * m->nq, m->nq);
      mj_kinematics(m, d);
      depth[i] = pairs_depth(m, d, g, np, B.buf, (int)(B.len / 8));
    }
    out = as_bytes(depth, n);
  }
  free(depth);
  release(&Q);
  release(&P);
  release(&B);
  return out;
}

/* {name: (sizeof, {field: offsetof})} of the records shared with Python. */
#define FIELD(T, f) PyTuple_Pack(2, PyUnicode_FromString(#f), PyLong_FromSsize_t(offsetof(T, f)))
static PyObject* record(Py_ssize_t size, PyObject* const* fields, int n) {
  PyObject* d = PyDict_New();
  for (int i = 0; d && i < n; i++) {
    if (!fields[i] || PyDict_SetItem(d, PyTuple_GET_ITEM(fields[i], 0),
                                     PyTuple_GET_ITEM(fields[i], 1))) {
      Py_CLEAR(d);
    }
  }
  for (int i = 0; i < n; i++) Py_XDECREF(fields[i]);
  return d ? Py_BuildValue("(nN)", size, d) : NULL;
}

static PyObject* mod_layout(PyObject* self, PyObject* noargs) {
  (void)self, (void)noargs;
  PyObject* block[] = {FIELD(Block, kind),  FIELD(Block, start), FIELD(Block, k),
                       FIELD(Block, hard),  FIELD(Block, perp),  FIELD(Block, id),
                       FIELD(Block, id2),   FIELD(Block, dof),   FIELD(Block, t0),
                       FIELD(Block, nt),    FIELD(Block, c),     FIELD(Block, local),
                       FIELD(Block, local2), FIELD(Block, value)};
  PyObject* term[] = {FIELD(Term, kind), FIELD(Term, id), FIELD(Term, coef)};
  PyObject* tun[] = {FIELD(Tunables, mu0),          FIELD(Tunables, max_step),
                     FIELD(Tunables, met_gain),     FIELD(Tunables, far_cost),
                     FIELD(Tunables, far_gain),     FIELD(Tunables, collision_tol),
                     FIELD(Tunables, null_tol),     FIELD(Tunables, natural_step),
                     FIELD(Tunables, natural_iter), FIELD(Tunables, pad_),
                     FIELD(Tunables, range_free)};
  return Py_BuildValue("{sNsNsN}", "Block", record(sizeof(Block), block, 14), "Term",
                       record(sizeof(Term), term, 3), "Tunables",
                       record(sizeof(Tunables), tun, 11));
}

static PyMethodDef Core_methods[] = {
    {"set_natural", (PyCFunction)Core_set_natural, METH_VARARGS,
     "set_natural(edof, escale, comfort, neutral, anc, pref_r, pref_J, pref_callback)."},
    {"natural", (PyCFunction)Core_natural, METH_NOARGS,
     "natural() -> (r, J): naturalness rows over the free dofs on the posture in data."},
    {"polish", (PyCFunction)Core_polish, METH_VARARGS,
     "polish(q, lo, hi, mov, stop, collide) -> (q, nat, it, hist, stop)."},
    {"rows", (PyCFunction)Core_rows, METH_NOARGS,
     "Write the raw rows into the shared r and J buffers (posture already in data)."},
    {"deepest", (PyCFunction)Core_deepest, METH_VARARGS,
     "deepest(pairs) -> the deepest penetration [m] among pairs outside the allowed ones."},
    {"evaluate", (PyCFunction)Core_evaluate, METH_VARARGS,
     "evaluate(q, collide) -> (r, J, norms, depth): scaled rows over the free dofs."},
    {"lm", (PyCFunction)Core_lm, METH_VARARGS,
     "lm(q, lo, hi, w, nat, posture, stop, max_iter, collide, early=True)"
     " -> (q, cost, done, it, met, hist, stop)."},
    {NULL, NULL, 0, NULL}};

static PyTypeObject CoreType = {
    PyVarObject_HEAD_INIT(NULL, 0).tp_name = "azee_mj._ikcore.Core",
    .tp_basicsize = sizeof(Core),
    .tp_flags = Py_TPFLAGS_DEFAULT | Py_TPFLAGS_HAVE_GC,
    .tp_traverse = (traverseproc)Core_traverse,
    .tp_clear = (inquiry)Core_clear,
    .tp_doc = "One posture problem compiled for the solver's inner loop.",
    .tp_new = PyType_GenericNew,
    .tp_init = (initproc)Core_init,
    .tp_dealloc = (destructor)Core_dealloc,
    .tp_methods = Core_methods,
};

static PyMethodDef mod_methods[] = {
    {"effort", mod_effort, METH_VARARGS,
     "effort(model_addr, data_addr, edof, anc, cols) -> (tau, J): gravity torques."},
    {"depth", mod_depth, METH_VARARGS,
     "depth(model_addr, data_addr, allowed) -> the deepest penetration [m] after mj_collision."},
    {"pairs_depth", mod_pairs_depth, METH_VARARGS,
     "pairs_depth(model_addr, data_addr, pairs, allowed) -> the deepest penetration [m] among "
     "geom pairs."},
    {"pairs_depths", mod_pairs_depths, METH_VARARGS,
     "pairs_depths(model_addr, data_addr, qpos, pairs, allowed) -> bytes of one pairs_depth "
     "per posture (its kinematics run)."},
    {"layout", mod_layout, METH_NOARGS,
     "layout() -> {record: (sizeof, {field: offsetof})} of Block, Term and Tunables."},
    {NULL, NULL, 0, NULL}};

static struct PyModuleDef moddef = {PyModuleDef_HEAD_INIT, .m_name = "_ikcore",
                                    .m_doc = "The posture solver's inner loop in C.",
                                    .m_size = -1, .m_methods = mod_methods};

PyMODINIT_FUNC PyInit__ikcore(void) {
  if (PyType_Ready(&CoreType) < 0) return NULL;
  PyObject* mod = PyModule_Create(&moddef);
  if (!mod) return NULL;
  PyObject* stops = PyTuple_New(STOP_COUNT);
  for (int i = 0; stops && i < STOP_COUNT; i++)
    PyTuple_SET_ITEM(stops, i, PyUnicode_FromString(STOP_NAMES[i]));
  Py_INCREF(&CoreType);
  if (!stops || PyModule_AddObject(mod, "STOPS", stops) < 0 ||
      PyModule_AddObject(mod, "Core", (PyObject*)&CoreType) < 0 ||
      PyModule_AddIntConstant(mod, "MJ_VERSION", mj_version()) < 0) {
    Py_DECREF(mod);
    return NULL;
  }
  return mod;
}
