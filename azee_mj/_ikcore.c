/* The posture solver's inner loop against MuJoCo's C API (see azee_mj/ik.py).

   A Core holds one problem compiled by ik.Plan: its row blocks, the free dofs and the
   per-body-pair contact floor and the geom pairs that can collide. It evaluates the scaled
   residual rows and their Jacobian over the free dofs (constraint rows, then one row per
   contact deeper than its pair's floor) and
   runs one Levenberg-Marquardt run whose steps are box-constrained QPs (mju_boxQP).
   Constraints of a form the core does not know are written by a Python callback.

   Only the buffer protocol is used (no numpy headers): arrays come in as contiguous float64
   or int32 buffers, results go out as bytes. Units: metres, radians. */

#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include <mujoco/mujoco.h>

/* Must match ik.py. */
#define MU0 1e-3
/* Least relative gain of an iteration once every row is within its tolerance. */
#define MET_GAIN 0.25
/* Far from every tolerance (cost over FAR_COST), a gain under FAR_GAIN is a stall: a local
   minimum that crawls is left early for the next start. */
#define FAR_COST 4.0
#define FAR_GAIN 1e-2
#define MAX_STEP 0.4
#define COLLISION_TOL 1e-4

enum { B_POINT = 0, B_ORIENT = 1, B_JOINT = 2, B_GENERIC = 3 };
enum { T_SITE = 0, T_BODY = 1 };

/* One block of rows. POINT: site - (const + sum c_k term_k). ORIENT: body axis a = R local
   against v = sign * (a constant unit vector, a body axis, or unit(const + sum c_k term_k)),
   along (3 rows: a - v) or perp (1 row: a . v).
   JOINT: qpos[adr] - value. GENERIC: written by the callback. */
typedef struct {
  int kind, start, k, hard, perp;
  int id;        /* site (POINT), body (ORIENT), qpos adr (JOINT) */
  int id2;       /* ORIENT: body of the target axis, -1 for a constant vector */
  int dof;       /* JOINT */
  int t0, nt;    /* POINT: terms */
  double c[3];   /* POINT: constant part of the target; ORIENT: constant v */
  double local[3], local2[3];
  double value;  /* JOINT target; ORIENT: sign of the target axis */
} Block;

typedef struct {
  PyObject_HEAD
  mjModel* m;
  mjData* d;
  PyObject* owner;      /* keeps the model/data Python objects alive */
  PyObject* callback;   /* fills the GENERIC blocks (or None) */
  Py_buffer rbuf, Jbuf; /* raw rows (nrows,) and (nrows, nv), shared with Python */
  int nblock, nrows, nfree, nterm, nv, nbody, has_generic;
  Block* blocks;
  int* term_kind;
  int* term_id;
  double* term_c;
  double* inv;    /* (nrows,) 1/tol per row (1 for generic rows) */
  int* free;      /* (nfree,) */
  double* floor;  /* (nbody * nbody,) */
  int npair;
  int* pair;      /* (npair, 2) geoms, each pair in mjCOLLISIONFUNC's type order */
  /* Geoms grouped in clusters (a hand, the head; a geom alone otherwise) and the pairs in
     runs of one cluster pair: a run whose clusters' bounding spheres are apart is skipped
     whole (none of its geom spheres can meet). */
  int nclu, nrun;
  int* gclu;      /* (ngeom,) cluster of each geom, -1 if it collides with nothing */
  int* run;       /* (nrun + 1,) first pair of each run */
  double *ccen, *crad; /* (nclu, 3), (nclu,) cluster spheres on the posture in data */
  double *tmp, *tmp2, *j1, *j2; /* (3, nv) */
  /* evaluation buffers: two sets for the LM (current and candidate) */
  int cap;
  double *r[2], *J[2];
  int rows[2];
  double *norms[2];
  double depth[2];
  int nhard;
  int* hard; /* (nhard, 2) row ranges of the hard constraints: one norm each */
  /* naturalness (set_natural) */
  int ne, npref;
  int* edof;
  double *escale, *comfort, *neutral;
  unsigned char* anc;
  PyObject* pref_cb;
  Py_buffer prbuf, pJbuf;
} Core;

static int grow(Core* s, int need) {
  if (need <= s->cap) return 0;
  int cap = need + 64;
  for (int b = 0; b < 2; b++) {
    double* r = realloc(s->r[b], sizeof(double) * cap);
    if (!r) return -1;
    s->r[b] = r;
    double* J = realloc(s->J[b], sizeof(double) * cap * (s->nfree ? s->nfree : 1));
    if (!J) return -1;
    s->J[b] = J;
  }
  s->cap = cap;
  return 0;
}

/* ------------------------------------------------------------------------------------ */
/* rows                                                                                  */

static void cross3(const double* a, const double* b, double* out) {
  out[0] = a[1] * b[2] - a[2] * b[1];
  out[1] = a[2] * b[0] - a[0] * b[2];
  out[2] = a[0] * b[1] - a[1] * b[0];
}

/* World axis R_body local and its Jacobian da/dq = -[a]x J_rot (3, nv) into ja. */
static void body_axis(Core* s, int bid, const double* local, double* a, double* ja) {
  const mjModel* m = s->m;
  mjData* d = s->d;
  int nv = s->nv;
  mju_mulMatVec3(a, d->xmat + 9 * bid, local);
  mj_jacBody(m, d, NULL, s->tmp, bid);
  for (int j = 0; j < nv; j++) {
    double w[3] = {s->tmp[j], s->tmp[nv + j], s->tmp[2 * nv + j]}, x[3];
    cross3(w, a, x); /* -a x w */
    ja[j] = x[0];
    ja[nv + j] = x[1];
    ja[2 * nv + j] = x[2];
  }
}

/* w = c + sum_k coef_k x_k over the block's point terms (sites, body origins) and its
   Jacobian (3, nv) into Jw. Uses tmp. */
static void combo(Core* s, const Block* B, double* w, double* Jw) {
  const mjModel* m = s->m;
  mjData* d = s->d;
  int nv = s->nv;
  for (int i = 0; i < 3; i++) w[i] = B->c[i];
  memset(Jw, 0, sizeof(double) * 3 * nv);
  for (int t = B->t0; t < B->t0 + B->nt; t++) {
    const double* x;
    if (s->term_kind[t] == T_SITE) {
      mj_jacSite(m, d, s->tmp, NULL, s->term_id[t]);
      x = d->site_xpos + 3 * s->term_id[t];
    } else {
      mj_jacBody(m, d, s->tmp, NULL, s->term_id[t]);
      x = d->xpos + 3 * s->term_id[t];
    }
    double c = s->term_c[t];
    for (int i = 0; i < 3; i++) w[i] += c * x[i];
    for (int i = 0; i < 3 * nv; i++) Jw[i] += c * s->tmp[i];
  }
}

/* Raw (unscaled) rows of every known block into rbuf/Jbuf, on the posture in d (after
   mj_kinematics and mj_comPos); then the callback for the generic ones. */
static int raw_rows(Core* s) {
  const mjModel* m = s->m;
  mjData* d = s->d;
  int nv = s->nv;
  double* R = (double*)s->rbuf.buf;
  double* JJ = (double*)s->Jbuf.buf;
  for (int b = 0; b < s->nblock; b++) {
    Block* B = s->blocks + b;
    double* r = R + B->start;
    double* J = JJ + (size_t)B->start * nv;
    if (B->kind == B_POINT) {
      double w[3];
      mj_jacSite(m, d, J, NULL, B->id);
      combo(s, B, w, s->j1);
      const double* p = d->site_xpos + 3 * B->id;
      for (int i = 0; i < 3; i++) r[i] = p[i] - w[i];
      for (int i = 0; i < 3 * nv; i++) J[i] -= s->j1[i];
    } else if (B->kind == B_ORIENT) {
      double a[3], v[3];
      body_axis(s, B->id, B->local, a, s->tmp2);
      double* dv = NULL;
      if (B->id2 >= 0) {
        body_axis(s, B->id2, B->local2, v, s->j1);
        for (int i = 0; i < 3; i++) v[i] *= B->value;
        for (int i = 0; i < 3 * nv; i++) s->j1[i] *= B->value;
        dv = s->j1;
      } else if (B->nt) {
        /* v = sign * unit(w), dv = sign * (I - u u^T) dw / |w| */
        double w[3];
        combo(s, B, w, s->j2);
        double nw = sqrt(w[0] * w[0] + w[1] * w[1] + w[2] * w[2]);
        if (nw < 1e-12) {
          v[0] = v[1] = v[2] = 0.0;
          memset(s->j1, 0, sizeof(double) * 3 * nv);
        } else {
          double u[3] = {w[0] / nw, w[1] / nw, w[2] / nw};
          for (int j = 0; j < nv; j++) {
            double x[3] = {s->j2[j], s->j2[nv + j], s->j2[2 * nv + j]};
            double ux = u[0] * x[0] + u[1] * x[1] + u[2] * x[2];
            for (int i = 0; i < 3; i++) s->j1[i * nv + j] = B->value * (x[i] - u[i] * ux) / nw;
          }
          for (int i = 0; i < 3; i++) v[i] = B->value * u[i];
        }
        dv = s->j1;
      } else {
        for (int i = 0; i < 3; i++) v[i] = B->c[i];
      }
      if (B->perp) {
        r[0] = a[0] * v[0] + a[1] * v[1] + a[2] * v[2];
        for (int j = 0; j < nv; j++) {
          double x = 0;
          for (int i = 0; i < 3; i++) {
            x += v[i] * s->tmp2[i * nv + j];
            if (dv) x += a[i] * dv[i * nv + j];
          }
          J[j] = x;
        }
      } else {
        for (int i = 0; i < 3; i++) r[i] = a[i] - v[i];
        for (int i = 0; i < 3 * nv; i++) J[i] = s->tmp2[i] - (dv ? dv[i] : 0.0);
      }
    } else if (B->kind == B_JOINT) {
      r[0] = d->qpos[B->id] - B->value;
      memset(J, 0, sizeof(double) * nv);
      J[B->dof] = 1.0;
    }
  }
  if (s->has_generic && s->callback != Py_None) {
    PyObject* out = PyObject_CallNoArgs(s->callback);
    if (!out) return -1;
    Py_DECREF(out);
  }
  return 0;
}

/* The penetrating contacts of geom pair (g1, g2) (in the type order of its function) on the
   posture in data, as MuJoCo's narrowphase finds them after mj_collision's bounding-sphere
   test, without the margin: their count, written to pc (mjMAXCONPAIR). */
static double dist2(const double* a, const double* b) {
  double x = a[0] - b[0], y = a[1] - b[1], z = a[2] - b[2];
  return x * x + y * y + z * z;
}

static int penetrations(const mjModel* m, mjData* d, int g1, int g2, mjPreContact* pc) {
  const double *x1 = d->geom_xpos + 3 * g1, *x2 = d->geom_xpos + 3 * g2;
  double dx = x1[0] - x2[0], dy = x1[1] - x2[1], dz = x1[2] - x2[2];
  double bound = m->geom_rbound[g1] + m->geom_rbound[g2];
  if (m->geom_rbound[g1] > 0 && m->geom_rbound[g2] > 0 &&
      dx * dx + dy * dy + dz * dz > bound * bound)
    return 0;
  return mjCOLLISIONFUNC[m->geom_type[g1]][m->geom_type[g2]](m, d, pc, g1, g2, 0.0);
}

/* The clusters' bounding spheres on the posture in data: each centred on its first geom and
   holding its geoms' bounding spheres (infinite with a plane). */
static void cluster_spheres(Core* s) {
  const mjModel* m = s->m;
  const mjData* d = s->d;
  for (int c = 0; c < s->nclu; c++) s->crad[c] = -1.0;
  for (int g = 0; g < m->ngeom; g++) {
    int c = s->gclu[g];
    if (c < 0) continue;
    if (s->crad[c] < 0) s->crad[c] = 0.0, mju_copy3(s->ccen + 3 * c, d->geom_xpos + 3 * g);
    double r = m->geom_rbound[g] > 0
                   ? sqrt(dist2(d->geom_xpos + 3 * g, s->ccen + 3 * c)) + m->geom_rbound[g]
                   : INFINITY;
    if (r > s->crad[c]) s->crad[c] = r;
  }
}

/* Appends to buffer set b, from row *rows on, one row per contact of pair p deeper than its
   body pair's floor: n . (J2 - J1) over the free dofs at the contact point; *worst: the
   deepest below a floor. Returns 0, or -1 out of memory. */
static int pair_rows(Core* s, int p, int b, int* rows, double* worst) {
  const mjModel* m = s->m;
  mjData* d = s->d;
  int nv = s->nv, nf = s->nfree;
  int g1 = s->pair[2 * p], g2 = s->pair[2 * p + 1];
  mjPreContact pc[mjMAXCONPAIR];
  int n = penetrations(m, d, g1, g2, pc);
  int b1 = m->geom_bodyid[g1], b2 = m->geom_bodyid[g2];
  double fl = s->floor[b1 * s->nbody + b2];
  for (int c = 0; c < n; c++) {
    const mjPreContact* con = pc + c;
    if (!(con->dist < fl)) continue;
    if (grow(s, *rows + 1)) return -1;
    if (fl - con->dist > *worst) *worst = fl - con->dist;
    mj_jac(m, d, s->j1, NULL, con->pos, b1);
    mj_jac(m, d, s->j2, NULL, con->pos, b2);
    double nrm[3] = {con->normal[0], con->normal[1], con->normal[2]};
    mju_normalize3(nrm); /* as mj_collision's contact frame */
    double* row = s->J[b] + (size_t)*rows * nf;
    for (int j = 0; j < nf; j++) {
      int f = s->free[j];
      double x = 0;
      for (int i = 0; i < 3; i++) x += nrm[i] * (s->j2[i * nv + f] - s->j1[i * nv + f]);
      row[j] = x / COLLISION_TOL;
    }
    s->r[b][(*rows)++] = (con->dist - fl) / COLLISION_TOL;
  }
  return 0;
}

/* Scaled rows over the free dofs of posture q into buffer set b; collision rows if collide.
   Returns 0, or -1 with a Python error set. */
static int evaluate(Core* s, const double* q, int collide, int b) {
  const mjModel* m = s->m;
  mjData* d = s->d;
  int nv = s->nv, nf = s->nfree;
  mju_copy(d->qpos, q, m->nq);
  mj_kinematics(m, d);
  mj_comPos(m, d);
  if (raw_rows(s)) return -1;
  if (grow(s, s->nrows)) return PyErr_NoMemory(), -1;
  double* R = (double*)s->rbuf.buf;
  double* JJ = (double*)s->Jbuf.buf;
  double* r = s->r[b];
  double* J = s->J[b];
  for (int i = 0; i < s->nrows; i++) {
    double w = s->inv[i];
    r[i] = R[i] * w;
    const double* src = JJ + (size_t)i * nv;
    double* dst = J + (size_t)i * nf;
    for (int j = 0; j < nf; j++) dst[j] = src[s->free[j]] * w;
  }
  for (int h = 0; h < s->nhard; h++) {
    double x = 0;
    for (int i = s->hard[2 * h]; i < s->hard[2 * h + 1]; i++) x += r[i] * r[i];
    s->norms[b][h] = sqrt(x);
  }
  int rows = s->nrows;
  double depth = 0.0;
  if (collide) {
    /* MuJoCo's narrowphase on the pair list, in mj_collision's order, only on the pairs
       that can move relative to each other and without the margin: a row is made only for
       a contact deeper than its floor (<= 0). */
    double worst = -INFINITY;
    cluster_spheres(s);
    for (int k = 0; k < s->nrun; k++) {
      int c1 = s->gclu[s->pair[2 * s->run[k]]], c2 = s->gclu[s->pair[2 * s->run[k] + 1]];
      double bound = s->crad[c1] + s->crad[c2];
      if (dist2(s->ccen + 3 * c1, s->ccen + 3 * c2) > bound * bound) continue;
      for (int p = s->run[k]; p < s->run[k + 1]; p++)
        if (pair_rows(s, p, b, &rows, &worst)) return PyErr_NoMemory(), -1;
    }
    if (worst > 0) depth = worst;
  }
  s->rows[b] = rows;
  s->depth[b] = depth;
  return 0;
}

static double max_norm(Core* s, int b) {
  double x = 0.0;
  for (int i = 0; i < s->nhard; i++)
    if (s->norms[b][i] > x) x = s->norms[b][i];
  return x;
}

/* ------------------------------------------------------------------------------------ */
/* naturalness: gravity torques (effort) and comfort (see azee_mj/natural.py)           */

/* tau (ne,) gravity torque each dof in edof holds, and, if J, its derivative (ne, ncols)
   with respect to qpos[cols]; anc[k * nv + i]: dof k is dof i or one of its ancestors. */
static void effort(const mjModel* m, const mjData* d, int ne, const int* edof,
                   const unsigned char* anc, int ncols, const int* cols, double* tau, double* J) {
  int nv = m->nv;
  const double* g = m->opt.gravity;
  for (int i = 0; i < ne; i++) {
    int di = edof[i], ji = m->dof_jntid[di], bi = m->dof_bodyid[di];
    const double* a = d->xaxis + 3 * ji;
    double r[3], rg[3], ga[3], u[3], t1[3], t2[3];
    for (int x = 0; x < 3; x++) r[x] = d->subtree_com[3 * bi + x] - d->xanchor[3 * ji + x];
    double M = m->body_subtreemass[bi];
    cross3(r, g, rg);
    tau[i] = M * (a[0] * rg[0] + a[1] * rg[1] + a[2] * rg[2]);
    if (!J) continue;
    cross3(g, a, ga);
    cross3(a, rg, t1);
    cross3(r, ga, t2);
    for (int x = 0; x < 3; x++) u[x] = t1[x] + t2[x];
    for (int k = 0; k < ncols; k++) {
      int dk = cols[k], jk = m->dof_jntid[dk], bk = m->dof_bodyid[dk];
      const double* ak = d->xaxis + 3 * jk;
      double v = 0.0;
      if (anc[dk * nv + di]) { /* k above or at i: i's axis and load turn about k */
        v = M * (u[0] * ak[0] + u[1] * ak[1] + u[2] * ak[2]);
      } else if (anc[di * nv + dk]) { /* k below i: only k's load moves */
        double rk[3], w[3];
        for (int x = 0; x < 3; x++) rk[x] = d->subtree_com[3 * bk + x] - d->xanchor[3 * jk + x];
        cross3(ak, rk, w);
        v = m->body_subtreemass[bk] * (w[0] * ga[0] + w[1] * ga[1] + w[2] * ga[2]);
      }
      J[(size_t)i * ncols + k] = v;
    }
  }
}

/* ------------------------------------------------------------------------------------ */
/* Python glue                                                                           */

static int get_buf(PyObject* o, Py_buffer* v, Py_ssize_t itemsize, Py_ssize_t n, const char* what,
                   int writable) {
  if (PyObject_GetBuffer(o, v, PyBUF_C_CONTIGUOUS | PyBUF_FORMAT | (writable ? PyBUF_WRITABLE : 0)))
    return -1;
  if (v->itemsize != itemsize || (n >= 0 && v->len != n * itemsize)) {
    PyErr_Format(PyExc_ValueError, "%s: expected %zd items of %zd bytes, got %zd bytes", what, n,
                 itemsize, v->len);
    PyBuffer_Release(v);
    return -1;
  }
  return 0;
}

static void Core_dealloc(Core* s) {
  if (s->rbuf.obj) PyBuffer_Release(&s->rbuf);
  if (s->Jbuf.obj) PyBuffer_Release(&s->Jbuf);
  Py_XDECREF(s->owner);
  Py_XDECREF(s->callback);
  free(s->blocks);
  free(s->term_kind);
  free(s->term_id);
  free(s->term_c);
  free(s->inv);
  free(s->free);
  free(s->floor);
  free(s->pair);
  free(s->gclu);
  free(s->run);
  free(s->ccen);
  free(s->crad);
  free(s->hard);
  free(s->edof);
  free(s->escale);
  free(s->comfort);
  free(s->neutral);
  free(s->anc);
  Py_XDECREF(s->pref_cb);
  if (s->prbuf.obj) PyBuffer_Release(&s->prbuf);
  if (s->pJbuf.obj) PyBuffer_Release(&s->pJbuf);
  free(s->tmp);
  free(s->tmp2);
  free(s->j1);
  free(s->j2);
  for (int b = 0; b < 2; b++) {
    free(s->r[b]);
    free(s->J[b]);
    free(s->norms[b]);
  }
  Py_TYPE(s)->tp_free((PyObject*)s);
}

/* Core(model_addr, data_addr, owner, blocks_i (nblock*10 int32), blocks_d (nblock*11 f64),
        terms_i (nterm*2 int32), terms_d (nterm f64), inv (nrows f64), free (int32),
        floor (nbody*nbody f64), r (nrows f64, writable), J (nrows*nv f64, writable), callback,
        hard (nhard*2 int32), pairs (npair*2 int32: the geom pairs to collide, in order),
        clusters (ngeom int32: each geom's cluster, -1 for none)) */
static int Core_init(Core* s, PyObject* args, PyObject* kw) {
  unsigned long long ma, da;
  PyObject *owner, *obi, *obd, *oti, *otd, *oinv, *ofree, *ofloor, *or_, *oJ, *cb, *ohard, *opair;
  PyObject* oclu;
  if (!PyArg_ParseTuple(args, "KKOOOOOOOOOOOOOO", &ma, &da, &owner, &obi, &obd, &oti, &otd, &oinv,
                        &ofree, &ofloor, &or_, &oJ, &cb, &ohard, &opair, &oclu))
    return -1;
  s->m = (mjModel*)(uintptr_t)ma;
  s->d = (mjData*)(uintptr_t)da;
  Py_INCREF(owner);
  s->owner = owner;
  Py_INCREF(cb);
  s->callback = cb;
  s->nv = s->m->nv;
  s->nbody = s->m->nbody;
  Py_buffer bi, bd, ti, td, inv, fr, fl;
  if (get_buf(obi, &bi, 4, -1, "blocks_i", 0)) return -1;
  s->nblock = (int)(bi.len / 40);
  if (get_buf(obd, &bd, 8, (Py_ssize_t)s->nblock * 11, "blocks_d", 0)) return -1;
  if (get_buf(oti, &ti, 4, -1, "terms_i", 0)) return -1;
  s->nterm = (int)(ti.len / 8);
  if (get_buf(otd, &td, 8, s->nterm, "terms_d", 0)) return -1;
  if (get_buf(oinv, &inv, 8, -1, "inv", 0)) return -1;
  s->nrows = (int)(inv.len / 8);
  if (get_buf(ofree, &fr, 4, -1, "free", 0)) return -1;
  s->nfree = (int)(fr.len / 4);
  if (get_buf(ofloor, &fl, 8, (Py_ssize_t)s->nbody * s->nbody, "floor", 0)) return -1;
  if (get_buf(or_, &s->rbuf, 8, s->nrows, "r", 1)) return -1;
  if (get_buf(oJ, &s->Jbuf, 8, (Py_ssize_t)s->nrows * s->nv, "J", 1)) return -1;

  s->blocks = calloc(s->nblock ? s->nblock : 1, sizeof(Block));
  const int32_t* I = bi.buf;
  const double* D = bd.buf;
  for (int b = 0; b < s->nblock; b++) {
    Block* B = s->blocks + b;
    const int32_t* x = I + 10 * b;
    const double* y = D + 11 * b;
    B->kind = x[0], B->start = x[1], B->k = x[2], B->hard = x[3], B->perp = x[4];
    B->id = x[5], B->id2 = x[6], B->dof = x[7], B->t0 = x[8], B->nt = x[9];
    for (int i = 0; i < 3; i++) B->c[i] = y[i], B->local[i] = y[3 + i], B->local2[i] = y[6 + i];
    B->value = y[9];
    if (B->kind == B_GENERIC) s->has_generic = 1;
  }
  Py_buffer hb;
  if (get_buf(ohard, &hb, 4, -1, "hard", 0)) return -1;
  s->nhard = (int)(hb.len / 8);
  s->hard = malloc(sizeof(int) * 2 * (s->nhard + 1));
  for (int h = 0; h < 2 * s->nhard; h++) s->hard[h] = ((int32_t*)hb.buf)[h];
  PyBuffer_Release(&hb);
  Py_buffer pb;
  if (get_buf(opair, &pb, 4, -1, "pairs", 0)) return -1;
  s->npair = (int)(pb.len / 8);
  s->pair = malloc(sizeof(int) * 2 * (s->npair + 1));
  const mjModel* m = s->m;
  for (int p = 0; p < s->npair; p++) {
    int g1 = ((int32_t*)pb.buf)[2 * p], g2 = ((int32_t*)pb.buf)[2 * p + 1];
    if (g1 < 0 || g2 < 0 || g1 >= m->ngeom || g2 >= m->ngeom ||
        m->geom_type[g1] > m->geom_type[g2] ||
        !mjCOLLISIONFUNC[m->geom_type[g1]][m->geom_type[g2]]) {
      PyBuffer_Release(&pb);
      PyErr_Format(PyExc_ValueError, "pairs: (%d, %d) is no geom pair in type order", g1, g2);
      return -1;
    }
    s->pair[2 * p] = g1, s->pair[2 * p + 1] = g2;
  }
  PyBuffer_Release(&pb);
  Py_buffer cb_;
  if (get_buf(oclu, &cb_, 4, m->ngeom, "clusters", 0)) return -1;
  s->gclu = malloc(sizeof(int) * (m->ngeom + 1));
  s->nclu = 0;
  for (int g = 0; g < m->ngeom; g++) {
    s->gclu[g] = ((int32_t*)cb_.buf)[g];
    if (s->gclu[g] >= s->nclu) s->nclu = s->gclu[g] + 1;
  }
  PyBuffer_Release(&cb_);
  s->run = malloc(sizeof(int) * (s->npair + 1));
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
  int nt = s->nterm ? s->nterm : 1;
  s->term_kind = malloc(sizeof(int) * nt);
  s->term_id = malloc(sizeof(int) * nt);
  s->term_c = malloc(sizeof(double) * nt);
  for (int t = 0; t < s->nterm; t++) {
    s->term_kind[t] = ((int32_t*)ti.buf)[2 * t];
    s->term_id[t] = ((int32_t*)ti.buf)[2 * t + 1];
    s->term_c[t] = ((double*)td.buf)[t];
  }
  s->inv = malloc(sizeof(double) * (s->nrows ? s->nrows : 1));
  memcpy(s->inv, inv.buf, inv.len);
  s->free = malloc(sizeof(int) * (s->nfree ? s->nfree : 1));
  for (int j = 0; j < s->nfree; j++) s->free[j] = ((int32_t*)fr.buf)[j];
  s->floor = malloc(fl.len);
  memcpy(s->floor, fl.buf, fl.len);
  PyBuffer_Release(&bi);
  PyBuffer_Release(&bd);
  PyBuffer_Release(&ti);
  PyBuffer_Release(&td);
  PyBuffer_Release(&inv);
  PyBuffer_Release(&fr);
  PyBuffer_Release(&fl);
  size_t n3 = sizeof(double) * 3 * s->nv;
  s->tmp = malloc(n3);
  s->tmp2 = malloc(n3);
  s->j1 = malloc(n3);
  s->j2 = malloc(n3);
  for (int b = 0; b < 2; b++) s->norms[b] = calloc(s->nhard + 1, sizeof(double));
  if (grow(s, s->nrows + 64)) {
    PyErr_NoMemory();
    return -1;
  }
  return 0;
}

static PyObject* as_bytes(const double* x, Py_ssize_t n) {
  return PyBytes_FromStringAndSize((const char*)x, n * (Py_ssize_t)sizeof(double));
}

/* rows(): the raw rows of the known blocks (and the callback's) on the posture in data. */
static PyObject* Core_rows(Core* s, PyObject* noargs) {
  if (raw_rows(s)) return NULL;
  Py_RETURN_NONE;
}

static int read_q(PyObject* o, Core* s, Py_buffer* v) {
  return get_buf(o, v, 8, s->m->nq, "q", 0);
}

/* evaluate(q, collide) -> (r bytes, J bytes (rows, nfree), norms bytes, depth) */
static PyObject* Core_evaluate(Core* s, PyObject* args) {
  PyObject* oq;
  int collide;
  if (!PyArg_ParseTuple(args, "Op", &oq, &collide)) return NULL;
  Py_buffer q;
  if (read_q(oq, s, &q)) return NULL;
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
  const mjModel* m = s->m;
  const int32_t* P = pb.buf;
  int n = (int)(pb.len / 8);
  mjPreContact pc[mjMAXCONPAIR];
  double depth = 0.0;
  for (int p = 0; p < n; p++) {
    int g1 = P[2 * p], g2 = P[2 * p + 1];
    if (s->floor[m->geom_bodyid[g1] * s->nbody + m->geom_bodyid[g2]] != 0.0) continue;
    int k = penetrations(m, s->d, g1, g2, pc);
    for (int c = 0; c < k; c++)
      if (-pc[c].dist > depth) depth = -pc[c].dist;
  }
  PyBuffer_Release(&pb);
  return PyFloat_FromDouble(depth);
}

/* H (nc x nc, symmetric) = A^T A and, with r, g = A^T r, for A the columns cols (nc of
   them; NULL: all n) of the rows x n matrix J; row by row, skipping exact zeros (a sparse
   row, a comfort row with one entry, costs its nonzeros only). */
static void normal_eq(const double* J, const double* r, int rows, int n, const int* cols,
                      int nc, double* H, double* g) {
  memset(H, 0, sizeof(double) * nc * nc);
  if (g) memset(g, 0, sizeof(double) * nc);
  for (int i = 0; i < rows; i++) {
    const double* row = J + (size_t)i * n;
    for (int a = 0; a < nc; a++) {
      double x = row[cols ? cols[a] : a];
      if (x == 0.0) continue;
      if (g) g[a] += x * r[i];
      double* Ha = H + (size_t)a * nc;
      if (cols)
        for (int b = a; b < nc; b++) Ha[b] += x * row[cols[b]];
      else
        for (int b = a; b < nc; b++) Ha[b] += x * row[b];
    }
  }
  for (int a = 0; a < nc; a++)
    for (int b = 0; b < a; b++) H[a * nc + b] = H[b * nc + a];
}

static double cost_of(Core* s, int b, const double* q, double posture, const double* w,
                      const double* nat) {
  double c = 0;
  for (int i = 0; i < s->rows[b]; i++) c += s->r[b][i] * s->r[b][i];
  if (posture) {
    double p = 0;
    for (int j = 0; j < s->nfree; j++) {
      double x = q[s->free[j]] - nat[j];
      p += w[j] * x * x;
    }
    c += posture * posture * p;
  }
  return c;
}

/* lm(q, lo, hi, w, nat, posture, stop, max_iter, collide, early=True)
     -> (q bytes, cost, done, iterations, met, history list)
   early: stop once met and slow (MET_GAIN), or slow far from the tolerances (FAR_GAIN).
   One Levenberg-Marquardt run on the constraint and collision rows plus, if posture > 0,
   rows posture * (q - nat) weighted by w (all per free dof); see Solver._lm. */
static PyObject* Core_lm(Core* s, PyObject* args) {
  PyObject *oq, *olo, *ohi, *ow, *onat;
  double posture, stop;
  int max_iter, collide, early = 1;
  if (!PyArg_ParseTuple(args, "OOOOOddip|p", &oq, &olo, &ohi, &ow, &onat, &posture, &stop,
                        &max_iter, &collide, &early))
    return NULL;
  int n = s->nfree, nq = s->m->nq;
  Py_buffer bq, blo, bhi, bw, bnat;
  if (read_q(oq, s, &bq)) return NULL;
  if (get_buf(olo, &blo, 8, n, "lo", 0)) return PyBuffer_Release(&bq), NULL;
  if (get_buf(ohi, &bhi, 8, n, "hi", 0)) return PyBuffer_Release(&bq), PyBuffer_Release(&blo), NULL;
  if (get_buf(ow, &bw, 8, n, "w", 0))
    return PyBuffer_Release(&bq), PyBuffer_Release(&blo), PyBuffer_Release(&bhi), NULL;
  if (get_buf(onat, &bnat, 8, n, "nat", 0))
    return PyBuffer_Release(&bq), PyBuffer_Release(&blo), PyBuffer_Release(&bhi),
           PyBuffer_Release(&bw), NULL;
  const double *lo = blo.buf, *hi = bhi.buf, *w = bw.buf, *nat = bnat.buf;
  size_t nn = (size_t)(n ? n : 1);
  double* q = malloc(sizeof(double) * nq);
  double* qn = malloc(sizeof(double) * nq);
  double* H = malloc(sizeof(double) * nn * nn);
  double* Hd = malloc(sizeof(double) * nn * nn);
  double* g = malloc(sizeof(double) * nn);
  double* res = malloc(sizeof(double) * nn);
  double* los = malloc(sizeof(double) * nn);
  double* his = malloc(sizeof(double) * nn);
  double* Rq = malloc(sizeof(double) * nn * (nn + 7));
  PyObject* history = PyList_New(0);
  PyObject* out = NULL;
  memcpy(q, bq.buf, sizeof(double) * nq);
  int cur = 0, it = 0, done = 0, met = 0, stalls = 0;
  double p2 = posture * posture, mu = MU0, nu = 2.0, cost;
  if (evaluate(s, q, collide, cur)) goto fail;
  cost = cost_of(s, cur, q, posture, w, nat);
  for (it = 1; it <= max_iter; it++) {
    if (max_norm(s, cur) <= stop && s->depth[cur] <= 2 * COLLISION_TOL) {
      out = Py_BuildValue("(NdiiiN)", as_bytes(q, nq), cost, 1, it - 1, 1, history);
      history = NULL;
      goto fail; /* not a failure: shared clean-up */
    }
    int k = s->rows[cur];
    const double* r = s->r[cur];
    const double* J = s->J[cur];
    normal_eq(J, r, k, n, NULL, n, H, g);
    if (posture)
      for (int a = 0; a < n; a++) {
        H[a * n + a] += p2 * w[a];
        g[a] += p2 * w[a] * (q[s->free[a]] - nat[a]);
      }
    double tr = 0;
    for (int a = 0; a < n; a++) tr += H[a * n + a];
    memcpy(Hd, H, sizeof(double) * n * n);
    double damp = mu * (tr / n + 1.0);
    for (int a = 0; a < n; a++) {
      Hd[a * n + a] += damp * w[a];
      double qa = q[s->free[a]];
      los[a] = fmax(lo[a] - qa, -MAX_STEP);
      his[a] = fmin(hi[a] - qa, MAX_STEP);
      res[a] = 0.0;
    }
    mju_boxQP(res, Rq, NULL, Hd, g, n, los, his);
    memcpy(qn, q, sizeof(double) * nq);
    for (int a = 0; a < n; a++) {
      double x = q[s->free[a]] + res[a];
      qn[s->free[a]] = x < lo[a] ? lo[a] : (x > hi[a] ? hi[a] : x);
    }
    int nxt = 1 - cur;
    if (evaluate(s, qn, collide, nxt)) goto fail;
    double cost_new = cost_of(s, nxt, qn, posture, w, nat);
    if (cost_new < cost) {
      double gain = (cost - cost_new) / cost;
      double gr = 0, rHr = 0;
      for (int a = 0; a < n; a++) {
        gr += g[a] * res[a];
        double x = 0;
        for (int b = 0; b < n; b++) x += H[a * n + b] * res[b];
        rHr += res[a] * x;
      }
      double predicted = -(2.0 * gr + rHr);
      double rho = predicted > 0 ? (cost - cost_new) / predicted : 0.0;
      memcpy(q, qn, sizeof(double) * nq);
      cur = nxt;
      cost = cost_new;
      double f = 1.0 - pow(2.0 * rho - 1.0, 3);
      mu = fmax(mu * fmax(1.0 / 3.0, f), 1e-7);
      nu = 2.0;
      PyObject* h = PyFloat_FromDouble(cost);
      PyList_Append(history, h);
      Py_DECREF(h);
      if (gain < (posture ? 0.02 : early && cost > FAR_COST ? FAR_GAIN : 1e-3)) {
        stalls++;
        if (posture || stalls >= 3) break;
      }
      /* Within tolerance already and no longer converging fast: a limit or a contact
         holds a row short of the stop; the polish starts from here. */
      if (!posture && early && gain < MET_GAIN && max_norm(s, cur) <= 1.0 &&
          s->depth[cur] <= 2 * COLLISION_TOL)
        break;
    } else {
      mu *= nu;
      nu *= 2.0;
      PyObject* h = PyFloat_FromDouble(cost);
      PyList_Append(history, h);
      Py_DECREF(h);
    }
    double rr = 0;
    for (int a = 0; a < n; a++) rr += res[a] * res[a];
    if (mu > 1e3 || rr < 1e-20) break;
  }
  if (it > max_iter) it = max_iter;
  {
    double mx = max_norm(s, cur);
    int ok_depth = s->depth[cur] <= 2 * COLLISION_TOL;
    done = mx <= stop && ok_depth;
    met = done || (mx <= 1.0 && ok_depth);
  }
  out = Py_BuildValue("(NdiiiN)", as_bytes(q, nq), cost, done, it, met, history);
  history = NULL;
fail:
  Py_XDECREF(history);
  free(q);
  free(qn);
  free(H);
  free(Hd);
  free(g);
  free(res);
  free(los);
  free(his);
  free(Rq);
  PyBuffer_Release(&bq);
  PyBuffer_Release(&blo);
  PyBuffer_Release(&bhi);
  PyBuffer_Release(&bw);
  PyBuffer_Release(&bnat);
  return out;
}

/* set_natural(edof int32, escale f64, comfort (nv) f64, neutral (nv) f64, anc (nv*nv) uint8,
               pref_r (npref) f64, pref_J (npref*nv) f64, pref_callback or None) */
static PyObject* Core_set_natural(Core* s, PyObject* args) {
  PyObject *oe, *os, *oc, *on, *oa, *opr, *opJ, *cb;
  if (!PyArg_ParseTuple(args, "OOOOOOOO", &oe, &os, &oc, &on, &oa, &opr, &opJ, &cb)) return NULL;
  Py_buffer e, sc, c, n, a;
  int nv = s->nv;
  if (get_buf(oe, &e, 4, -1, "edof", 0)) return NULL;
  int ne = (int)(e.len / 4);
  if (get_buf(os, &sc, 8, ne, "escale", 0)) return PyBuffer_Release(&e), NULL;
  if (get_buf(oc, &c, 8, nv, "comfort", 0)) return PyBuffer_Release(&e), PyBuffer_Release(&sc), NULL;
  if (get_buf(on, &n, 8, nv, "neutral", 0))
    return PyBuffer_Release(&e), PyBuffer_Release(&sc), PyBuffer_Release(&c), NULL;
  if (get_buf(oa, &a, 1, (Py_ssize_t)nv * nv, "anc", 0))
    return PyBuffer_Release(&e), PyBuffer_Release(&sc), PyBuffer_Release(&c),
           PyBuffer_Release(&n), NULL;
  s->ne = ne;
  free(s->edof);
  free(s->escale);
  free(s->comfort);
  free(s->neutral);
  free(s->anc);
  s->edof = malloc(sizeof(int) * (ne + 1));
  for (int i = 0; i < ne; i++) s->edof[i] = ((int32_t*)e.buf)[i];
  s->escale = malloc(sizeof(double) * (ne + 1));
  memcpy(s->escale, sc.buf, sc.len);
  s->comfort = malloc(c.len);
  memcpy(s->comfort, c.buf, c.len);
  s->neutral = malloc(n.len);
  memcpy(s->neutral, n.buf, n.len);
  s->anc = malloc(a.len);
  memcpy(s->anc, a.buf, a.len);
  PyBuffer_Release(&e);
  PyBuffer_Release(&sc);
  PyBuffer_Release(&c);
  PyBuffer_Release(&n);
  PyBuffer_Release(&a);
  if (s->prbuf.obj) PyBuffer_Release(&s->prbuf);
  if (s->pJbuf.obj) PyBuffer_Release(&s->pJbuf);
  if (get_buf(opr, &s->prbuf, 8, -1, "pref_r", 1)) return NULL;
  s->npref = (int)(s->prbuf.len / 8);
  if (get_buf(opJ, &s->pJbuf, 8, (Py_ssize_t)s->npref * nv, "pref_J", 1)) return NULL;
  Py_XDECREF(s->pref_cb);
  Py_INCREF(cb);
  s->pref_cb = cb;
  Py_RETURN_NONE;
}

/* Naturalness rows (ne effort, nfree comfort, npref preferences) and their Jacobian over
   the free dofs, on the posture in d (after evaluate). Returns the row count or -1. */
static int natural_rows(Core* s, double* rn, double* Jn) {
  const mjModel* m = s->m;
  mjData* d = s->d;
  int nf = s->nfree, ne = s->ne, nv = s->nv;
  effort(m, d, ne, s->edof, s->anc, nf, s->free, rn, Jn);
  for (int i = 0; i < ne; i++) {
    rn[i] *= s->escale[i];
    for (int k = 0; k < nf; k++) Jn[(size_t)i * nf + k] *= s->escale[i];
  }
  memset(Jn + (size_t)ne * nf, 0, sizeof(double) * nf * nf);
  for (int k = 0; k < nf; k++) {
    int f = s->free[k];
    rn[ne + k] = s->comfort[f] * (d->qpos[f] - s->neutral[f]);
    Jn[(size_t)(ne + k) * nf + k] = s->comfort[f];
  }
  if (s->npref) {
    PyObject* out = PyObject_CallNoArgs(s->pref_cb);
    if (!out) return -1;
    Py_DECREF(out);
    const double* pr = s->prbuf.buf;
    const double* pJ = s->pJbuf.buf;
    for (int i = 0; i < s->npref; i++) {
      rn[ne + nf + i] = pr[i];
      for (int k = 0; k < nf; k++) Jn[(size_t)(ne + nf + i) * nf + k] = pJ[(size_t)i * nv + s->free[k]];
    }
  }
  return ne + nf + s->npref;
}

static double dot(const double* a, const double* b, int n) {
  double x = 0;
  for (int i = 0; i < n; i++) x += a[i] * b[i];
  return x;
}

/* polish(q, lo, hi, mov (int32, indices into free), stop, collide, iters, step0, null_tol,
          max_step) -> (q bytes, natural cost, iterations, history list)
   The most natural posture among those that meet the constraints; see Solver._polish. */
static PyObject* Core_polish(Core* s, PyObject* args) {
  PyObject *oq, *olo, *ohi, *omov;
  double stop, step0, null_tol, max_step;
  int collide, iters;
  if (!PyArg_ParseTuple(args, "OOOOdpiddd", &oq, &olo, &ohi, &omov, &stop, &collide, &iters,
                        &step0, &null_tol, &max_step))
    return NULL;
  int n = s->nfree, nq = s->m->nq;
  Py_buffer bq, blo, bhi, bmov;
  if (read_q(oq, s, &bq)) return NULL;
  if (get_buf(olo, &blo, 8, n, "lo", 0)) return PyBuffer_Release(&bq), NULL;
  if (get_buf(ohi, &bhi, 8, n, "hi", 0)) return PyBuffer_Release(&bq), PyBuffer_Release(&blo), NULL;
  if (get_buf(omov, &bmov, 4, -1, "mov", 0))
    return PyBuffer_Release(&bq), PyBuffer_Release(&blo), PyBuffer_Release(&bhi), NULL;
  const double *lo = blo.buf, *hi = bhi.buf;
  const int32_t* mov = bmov.buf;
  int nm = (int)(bmov.len / 4);
  int nrn = s->ne + n + s->npref;
  size_t nn = (size_t)(n ? n : 1), mm = (size_t)(nm ? nm : 1);
  double* q = malloc(sizeof(double) * nq);
  double* qn = malloc(sizeof(double) * nq);
  double* rn[2] = {malloc(sizeof(double) * (nrn + 1)), malloc(sizeof(double) * (nrn + 1))};
  double* Jn[2] = {malloc(sizeof(double) * (nrn + 1) * nn), malloc(sizeof(double) * (nrn + 1) * nn)};
  double* Hn = malloc(sizeof(double) * mm * mm);
  double* gn = malloc(sizeof(double) * mm);
  double* G = malloc(sizeof(double) * mm * mm); /* Gram matrix of the constraint rows */
  double* B = malloc(sizeof(double) * mm * mm);
  double* y = malloc(sizeof(double) * mm);
  double* stepm = malloc(sizeof(double) * mm);
  double* step = malloc(sizeof(double) * nn);
  double* H = malloc(sizeof(double) * nn * nn);
  double* g = malloc(sizeof(double) * nn);
  double* res = malloc(sizeof(double) * nn);
  double* los = malloc(sizeof(double) * nn);
  double* his = malloc(sizeof(double) * nn);
  double* Rq = malloc(sizeof(double) * nn * (nn + 7));
  unsigned char* locked = malloc(mm);
  unsigned char* out = malloc(mm);
  PyObject* history = PyList_New(0);
  PyObject* result = NULL;
  memcpy(q, bq.buf, sizeof(double) * nq);
  int cur = 0, it = 0, stalls = 0, moves = 1;
  double nat = 0.0, radius = step0;
  if (evaluate(s, q, collide, cur)) goto done;
  if (natural_rows(s, rn[cur], Jn[cur]) < 0) goto done;
  nat = dot(rn[cur], rn[cur], nrn);
  for (it = 1; it <= iters; it++) {
    int rows = s->rows[cur];
    const double* J = s->J[cur];
    const double* rnc = rn[cur];
    const double* Jnc = Jn[cur];
    normal_eq(Jnc, rnc, nrn, n, mov, nm, Hn, gn); /* Gauss-Newton model of the naturalness */
    /* The step minimises the naturalness model plus rho |A s|^2 (A: the constraint and
       collision rows), rho so large that a direction of A with a singular value over
       null_tol of their scale is held still: the null-space step without a factorisation
       of A (one Cholesky of nm x nm). A joint the step would take out of its range is held
       too, and the step solved again. */
    normal_eq(J, NULL, rows, n, mov, nm, G, NULL);
    double trg = 0, trn = 0;
    for (int a = 0; a < nm; a++) trg += G[a * nm + a], trn += Hn[a * nm + a];
    double hs = trn / (nm ? nm : 1) + 1e-12;
    double rho = trg > 0 ? hs / (null_tol * null_tol * trg) : 0.0;
    double hold = hs / (null_tol * null_tol);
    memset(locked, 0, mm);
    for (int pass = 0; pass < 3; pass++) {
      for (int a = 0; a < nm; a++) {
        for (int b = a; b < nm; b++) B[a * nm + b] = B[b * nm + a] = Hn[a * nm + b] + rho * G[a * nm + b];
        B[a * nm + a] += 1e-3 * hs + (locked[a] ? hold : 0.0);
        y[a] = -gn[a];
      }
      mju_cholFactor(B, nm, 0.0);
      mju_cholSolve(stepm, B, y, nm);
      int any = 0;
      for (int a = 0; a < nm; a++) {
        if (locked[a]) stepm[a] = 0.0;
        int f = mov[a];
        double qm = q[s->free[f]] + stepm[a];
        out[a] = (qm < lo[f] - 1e-12) || (qm > hi[f] + 1e-12);
        if (out[a] && !locked[a]) any = 1;
      }
      if (!any) break;
      for (int a = 0; a < nm; a++)
        if (out[a]) locked[a] = 1;
    }
    moves = 0;
    for (int a = 0; a < nm; a++) moves |= fabs(stepm[a]) > 1e-12;
    if (!moves) break; /* no freedom left */
    memset(step, 0, sizeof(double) * n);
    double big = 0;
    for (int a = 0; a < nm; a++) {
      step[mov[a]] = stepm[a];
      if (fabs(stepm[a]) > big) big = fabs(stepm[a]);
    }
    if (big > radius)
      for (int j = 0; j < n; j++) step[j] *= radius / big;
    memcpy(qn, q, sizeof(double) * nq);
    for (int j = 0; j < n; j++) {
      double x = q[s->free[j]] + step[j];
      qn[s->free[j]] = x < lo[j] ? lo[j] : (x > hi[j] ? hi[j] : x);
    }
    int nxt = 1 - cur;
    if (evaluate(s, qn, collide, nxt)) goto done;
    for (int back = 0; back < 2; back++) { /* back onto the constraints (first-order step) */
      int kr = s->rows[nxt];
      if (!kr || max_norm(s, nxt) <= stop) break;
      const double* Jx = s->J[nxt];
      const double* rx = s->r[nxt];
      normal_eq(Jx, rx, kr, n, NULL, n, H, g);
      double trh = 0;
      for (int a = 0; a < n; a++) trh += H[a * n + a];
      for (int a = 0; a < n; a++) {
        H[a * n + a] += 1e-9 * (trh / n + 1.0);
        los[a] = lo[a] - qn[s->free[a]];
        his[a] = hi[a] - qn[s->free[a]];
        res[a] = 0.0;
      }
      mju_boxQP(res, Rq, NULL, H, g, n, los, his);
      for (int a = 0; a < n; a++) {
        double x = qn[s->free[a]] + res[a];
        qn[s->free[a]] = x < lo[a] ? lo[a] : (x > hi[a] ? hi[a] : x);
      }
      if (evaluate(s, qn, collide, nxt)) goto done;
    }
    if (natural_rows(s, rn[nxt], Jn[nxt]) < 0) goto done;
    double nat_new = dot(rn[nxt], rn[nxt], nrn);
    double bound = fmax(stop, max_norm(s, cur));
    int ok = max_norm(s, nxt) <= bound && s->depth[nxt] <= fmax(s->depth[cur], 1e-5);
    if (ok && nat_new < nat) {
      double gain = (nat - nat_new) / fmax(nat, 1e-12);
      memcpy(q, qn, sizeof(double) * nq);
      cur = nxt;
      nat = nat_new;
      radius = fmin(2.0 * radius, max_step);
      stalls = gain < 1e-3 ? stalls + 1 : 0; /* a step that gains under 0.1 % */
    } else {
      radius *= 0.25;
      stalls += radius < 1e-3 ? 1 : 0; /* no step gains, down to a milliradian */
    }
    PyObject* h = PyFloat_FromDouble(dot(s->r[cur], s->r[cur], s->rows[cur]));
    PyList_Append(history, h);
    Py_DECREF(h);
    if (stalls >= 2) break;
  }
  if (it > iters) it = iters;
  result = Py_BuildValue("(NdiN)", as_bytes(q, nq), nat, it, history);
  history = NULL;
done:
  Py_XDECREF(history);
  free(q); free(qn); free(rn[0]); free(rn[1]); free(Jn[0]); free(Jn[1]); free(Hn); free(gn);
  free(G); free(B); free(y); free(stepm); free(step); free(H); free(g); free(res);
  free(los); free(his); free(Rq); free(locked); free(out);
  PyBuffer_Release(&bq);
  PyBuffer_Release(&blo);
  PyBuffer_Release(&bhi);
  PyBuffer_Release(&bmov);
  return result;
}

/* natural() -> (r bytes, J bytes (rows, nfree)): the naturalness rows on the posture in
   data (after mj_kinematics and mj_comPos). */
static PyObject* Core_natural(Core* s, PyObject* noargs) {
  int nrn = s->ne + s->nfree + s->npref;
  double* r = malloc(sizeof(double) * (nrn + 1));
  double* J = malloc(sizeof(double) * (nrn + 1) * (s->nfree + 1));
  PyObject* out = NULL;
  if (natural_rows(s, r, J) >= 0)
    out = Py_BuildValue("(NN)", as_bytes(r, nrn), as_bytes(J, (Py_ssize_t)nrn * s->nfree));
  free(r);
  free(J);
  return out;
}

/* effort(model_addr, data_addr, edof int32, anc uint8 (nv*nv), cols int32)
     -> (tau bytes (ne,), J bytes (ne, ncols)) */
static PyObject* mod_effort(PyObject* self, PyObject* args) {
  unsigned long long ma, da;
  PyObject *oe, *oa, *oc;
  if (!PyArg_ParseTuple(args, "KKOOO", &ma, &da, &oe, &oa, &oc)) return NULL;
  const mjModel* m = (const mjModel*)(uintptr_t)ma;
  const mjData* d = (const mjData*)(uintptr_t)da;
  Py_buffer e, a, c;
  if (get_buf(oe, &e, 4, -1, "edof", 0)) return NULL;
  if (get_buf(oa, &a, 1, (Py_ssize_t)m->nv * m->nv, "anc", 0)) return PyBuffer_Release(&e), NULL;
  if (get_buf(oc, &c, 4, -1, "cols", 0)) return PyBuffer_Release(&e), PyBuffer_Release(&a), NULL;
  int ne = (int)(e.len / 4), nc = (int)(c.len / 4);
  int* ed = malloc(sizeof(int) * (ne + 1));
  int* cl = malloc(sizeof(int) * (nc + 1));
  for (int i = 0; i < ne; i++) ed[i] = ((int32_t*)e.buf)[i];
  for (int i = 0; i < nc; i++) cl[i] = ((int32_t*)c.buf)[i];
  double* tau = malloc(sizeof(double) * (ne + 1));
  double* J = malloc(sizeof(double) * (ne + 1) * (nc + 1));
  effort(m, d, ne, ed, a.buf, nc, cl, tau, J);
  PyObject* out = Py_BuildValue("(NN)", as_bytes(tau, ne), as_bytes(J, (Py_ssize_t)ne * nc));
  free(ed); free(cl); free(tau); free(J);
  PyBuffer_Release(&e);
  PyBuffer_Release(&a);
  PyBuffer_Release(&c);
  return out;
}

static PyMethodDef Core_methods[] = {
    {"set_natural", (PyCFunction)Core_set_natural, METH_VARARGS,
     "set_natural(edof, escale, comfort, neutral, anc, pref_r, pref_J, pref_callback)."},
    {"natural", (PyCFunction)Core_natural, METH_NOARGS,
     "natural() -> (r, J): naturalness rows over the free dofs on the posture in data."},
    {"polish", (PyCFunction)Core_polish, METH_VARARGS,
     "polish(q, lo, hi, mov, stop, collide, iters, step0, null_tol, max_step)"
     " -> (q, nat, it, hist)."},
    {"rows", (PyCFunction)Core_rows, METH_NOARGS,
     "Write the raw rows into the shared r and J buffers (posture already in data)."},
    {"deepest", (PyCFunction)Core_deepest, METH_VARARGS,
     "deepest(pairs) -> the deepest penetration [m] among pairs outside the allowed ones."},
    {"evaluate", (PyCFunction)Core_evaluate, METH_VARARGS,
     "evaluate(q, collide) -> (r, J, norms, depth): scaled rows over the free dofs."},
    {"lm", (PyCFunction)Core_lm, METH_VARARGS,
     "lm(q, lo, hi, w, nat, posture, stop, max_iter, collide) -> (q, cost, done, it, met, hist)."},
    {NULL, NULL, 0, NULL}};

static PyTypeObject CoreType = {
    PyVarObject_HEAD_INIT(NULL, 0).tp_name = "azee_mj._ikcore.Core",
    .tp_basicsize = sizeof(Core),
    .tp_flags = Py_TPFLAGS_DEFAULT,
    .tp_doc = "One posture problem compiled for the solver's inner loop.",
    .tp_new = PyType_GenericNew,
    .tp_init = (initproc)Core_init,
    .tp_dealloc = (destructor)Core_dealloc,
    .tp_methods = Core_methods,
};

static PyMethodDef mod_methods[] = {
    {"effort", mod_effort, METH_VARARGS,
     "effort(model_addr, data_addr, edof, anc, cols) -> (tau, J): gravity torques."},
    {NULL, NULL, 0, NULL}};

static struct PyModuleDef moddef = {PyModuleDef_HEAD_INIT, "_ikcore",
                                    "The posture solver's inner loop in C.", -1, mod_methods};

PyMODINIT_FUNC PyInit__ikcore(void) {
  if (PyType_Ready(&CoreType) < 0) return NULL;
  PyObject* mod = PyModule_Create(&moddef);
  if (!mod) return NULL;
  Py_INCREF(&CoreType);
  if (PyModule_AddObject(mod, "Core", (PyObject*)&CoreType) < 0) {
    Py_DECREF(&CoreType);
    Py_DECREF(mod);
    return NULL;
  }
  if (PyModule_AddIntConstant(mod, "MJ_VERSION", mj_version()) < 0) return NULL;
  if (PyModule_AddObject(mod, "MU0", PyFloat_FromDouble(MU0)) < 0) return NULL;
  if (PyModule_AddObject(mod, "MAX_STEP", PyFloat_FromDouble(MAX_STEP)) < 0) return NULL;
  if (PyModule_AddObject(mod, "COLLISION_TOL", PyFloat_FromDouble(COLLISION_TOL)) < 0)
    return NULL;
  if (PyModule_AddObject(mod, "MET_GAIN", PyFloat_FromDouble(MET_GAIN)) < 0) return NULL;
  if (PyModule_AddObject(mod, "FAR_COST", PyFloat_FromDouble(FAR_COST)) < 0) return NULL;
  if (PyModule_AddObject(mod, "FAR_GAIN", PyFloat_FromDouble(FAR_GAIN)) < 0) return NULL;
  return mod;
}
