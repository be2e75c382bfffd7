/* Constraint rows: the blocks' raw rows from MuJoCo's Jacobians, and their scaled
   evaluation over the free dofs (with the collision rows). See _ikcore_shared.h. */
#include "_ikcore_shared.h"

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

/* w = c + sum_t coef_t x_t over the block's point terms (sites, body origins) and its
   Jacobian (3, nv) into Jw. Uses tmp. */
static void combo(Core* s, const Block* B, double* w, double* Jw) {
  const mjModel* m = s->m;
  mjData* d = s->d;
  int nv = s->nv;
  for (int i = 0; i < 3; i++) w[i] = B->c[i];
  memset(Jw, 0, sizeof(double) * 3 * nv);
  for (int t = B->t0; t < B->t0 + B->nt; t++) {
    const Term* T = s->terms + t;
    const double* x;
    if (T->kind == T_SITE) {
      mj_jacSite(m, d, s->tmp, NULL, T->id);
      x = d->site_xpos + 3 * T->id;
    } else {
      mj_jacBody(m, d, s->tmp, NULL, T->id);
      x = d->xpos + 3 * T->id;
    }
    double c = T->coef;
    for (int i = 0; i < 3; i++) w[i] += c * x[i];
    for (int i = 0; i < 3 * nv; i++) Jw[i] += c * s->tmp[i];
  }
}

static void point_rows(Core* s, const Block* B, double* r, double* J) {
  double w[3];
  int nv = s->nv;
  mj_jacSite(s->m, s->d, J, NULL, B->id);
  combo(s, B, w, s->j1);
  const double* p = s->d->site_xpos + 3 * B->id;
  for (int i = 0; i < 3; i++) r[i] = p[i] - w[i];
  for (int i = 0; i < 3 * nv; i++) J[i] -= s->j1[i];
}

/* The target direction v of an ORIENT block and its Jacobian (into j1; NULL if constant). */
static const double* orient_target(Core* s, const Block* B, double* v) {
  int nv = s->nv;
  if (B->id2 >= 0) {
    body_axis(s, B->id2, B->local2, v, s->j1);
    for (int i = 0; i < 3; i++) v[i] *= B->value;
    for (int i = 0; i < 3 * nv; i++) s->j1[i] *= B->value;
    return s->j1;
  }
  if (!B->nt) {
    for (int i = 0; i < 3; i++) v[i] = B->c[i];
    return NULL;
  }
  /* v = sign * unit(w), dv = sign * (I - u u^T) dw / |w| */
  double w[3];
  combo(s, B, w, s->j2);
  double nw = sqrt(w[0] * w[0] + w[1] * w[1] + w[2] * w[2]);
  if (nw < 1e-12) {
    v[0] = v[1] = v[2] = 0.0;
    memset(s->j1, 0, sizeof(double) * 3 * nv);
    return s->j1;
  }
  double u[3] = {w[0] / nw, w[1] / nw, w[2] / nw};
  for (int j = 0; j < nv; j++) {
    double x[3] = {s->j2[j], s->j2[nv + j], s->j2[2 * nv + j]};
    double ux = u[0] * x[0] + u[1] * x[1] + u[2] * x[2];
    for (int i = 0; i < 3; i++) s->j1[i * nv + j] = B->value * (x[i] - u[i] * ux) / nw;
  }
  for (int i = 0; i < 3; i++) v[i] = B->value * u[i];
  return s->j1;
}

static void orient_rows(Core* s, const Block* B, double* r, double* J) {
  int nv = s->nv;
  double a[3], v[3];
  body_axis(s, B->id, B->local, a, s->tmp2);
  const double* dv = orient_target(s, B, v);
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
}

/* Raw (unscaled) rows of every known block into rbuf/Jbuf, on the posture in d (after
   mj_kinematics and mj_comPos); then the callback for the generic ones. Returns 0, or -1
   with the callback's Python error set. */
int raw_rows(Core* s) {
  int nv = s->nv;
  double* R = (double*)s->rbuf.buf;
  double* JJ = (double*)s->Jbuf.buf;
  for (int b = 0; b < s->nblock; b++) {
    const Block* B = s->blocks + b;
    double* r = R + B->start;
    double* J = JJ + (size_t)B->start * nv;
    if (B->kind == B_POINT) {
      point_rows(s, B, r, J);
    } else if (B->kind == B_ORIENT) {
      orient_rows(s, B, r, J);
    } else if (B->kind == B_JOINT) {
      r[0] = s->d->qpos[B->id] - B->value;
      memset(J, 0, sizeof(double) * nv);
      J[B->dof] = 1.0;
    }
  }
  if (s->has_generic && s->callback && s->callback != Py_None) {
    PyObject* out = PyObject_CallNoArgs(s->callback);
    if (!out) return -1;
    Py_DECREF(out);
  }
  return 0;
}

/* A hard constraint's norm from its scaled rows r, in the report's measure so that it is 1
   where the residual reaches the tolerance: H = (first row, end row, kind, tol). An
   orientation's rows (HARD_CHORD: 3-row groups a - v; HARD_SINE: rows a . v, each over tol)
   measure the chord or the sine of an angle: each group's angle over tol, the root sum of
   their squares (a look's two eyes: at least the larger). */
static double hard_norm(const double* H, const double* r) {
  int first = (int)H[0], end = (int)H[1], kind = (int)H[2] & ~HARD_RANGE;
  double tol = H[3], x = 0;
  if (kind == HARD_LINEAR) {
    for (int i = first; i < end; i++) x += r[i] * r[i];
    return sqrt(x);
  }
  int g = kind == HARD_CHORD ? 3 : 1;
  for (int i = first; i + g <= end; i += g) {
    double c = 0;
    for (int j = i; j < i + g; j++) c += r[j] * r[j];
    c = sqrt(c) * tol;
    double angle = kind == HARD_CHORD ? 2.0 * asin(fmin(0.5 * c, 1.0)) : asin(fmin(c, 1.0));
    x += (angle / tol) * (angle / tol);
  }
  return sqrt(x);
}

/* A ranged orientation's scaled rows r[first, end) and their Jacobian J (nf columns), of
   norm x (hard_norm), in its dead zone: zero within range_free of its tolerance, shrunk
   beyond it to reach their full value at it; returns the norm so measured (0 in the dead
   zone, 1 at the tolerance: "met" and "done" compare it as any other). The Jacobian is
   scaled by the same factor, its own derivative left out (Gauss-Newton's approximation:
   steps near the zone's edge come out short, and the damping takes them as they come). */
static double ranged(const Core* s, const double* H, double x, double* r, double* J, int nf) {
  double free = s->tun.range_free, f = x > free ? (x - free) / x : 0.0;
  for (int i = (int)H[0]; i < (int)H[1]; i++) {
    r[i] *= f;
    for (int j = 0; j < nf; j++) J[(size_t)i * nf + j] *= f;
  }
  return x > free ? (x - free) / (1.0 - free) : 0.0;
}

/* Scaled rows over the free dofs of posture q into buffer set b; collision rows if collide.
   Returns 0, or -1 with a Python error set. */
int evaluate(Core* s, const double* q, int collide, int b) {
  const mjModel* m = s->m;
  mjData* d = s->d;
  int nv = s->nv, nf = s->nfree;
  mju_copy(d->qpos, q, m->nq);
  mj_kinematics(m, d);
  mj_comPos(m, d);
  if (raw_rows(s)) return -1;
  if (grow(s, s->nrows)) return PyErr_NoMemory(), -1;
  const double* R = (const double*)s->rbuf.buf;
  const double* JJ = (const double*)s->Jbuf.buf;
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
    const double* H = s->hard + 4 * h;
    double x = hard_norm(H, r);
    s->norms[b][h] = (int)H[2] & HARD_RANGE ? ranged(s, H, x, r, J, nf) : x;
  }
  int rows = s->nrows;
  double depth = 0.0;
  if (collide && collision_rows(s, b, &rows, &depth)) return PyErr_NoMemory(), -1;
  s->rows[b] = rows;
  s->depth[b] = depth;
  return 0;
}

/* The largest row norm of a hard constraint in buffer set b. */
double max_norm(const Core* s, int b) {
  double x = 0.0;
  for (int i = 0; i < s->nhard; i++)
    if (s->norms[b][i] > x) x = s->norms[b][i];
  return x;
}
