/* The Levenberg-Marquardt run on the constraint and collision rows, and the polish toward
   the most natural posture that keeps them (see azee_mj/ik.py, Solver._lm and _polish).
   Each run reports why it stopped (Stop). See _ikcore_shared.h. */
#include "_ikcore_shared.h"

/* H (nc x nc, symmetric) = A^T A and, with r, g = A^T r, for A the columns cols (nc of
   them; NULL: all n) of the rows x n matrix J; row by row, skipping exact zeros (a sparse
   row, a comfort row with one entry, costs its nonzeros only). */
static void normal_eq(const double* J, const double* r, int rows, int n, const int32_t* cols,
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

static double dot(const double* a, const double* b, int n) {
  double x = 0;
  for (int i = 0; i < n; i++) x += a[i] * b[i];
  return x;
}

/* q[free] + step clipped to [lo, hi] into qn (the other dofs copied from q; qn may be q). */
static void step_to(const Core* s, const double* q, const double* step, const double* lo,
                    const double* hi, double* qn) {
  if (qn != q) memcpy(qn, q, sizeof(double) * s->m->nq);
  for (int a = 0; a < s->nfree; a++) {
    double x = q[s->free[a]] + step[a];
    qn[s->free[a]] = x < lo[a] ? lo[a] : (x > hi[a] ? hi[a] : x);
  }
}

/* Frees every non-NULL buffer of a workspace of n pointers. */
static void free_all(double** p, int n) {
  for (int i = 0; i < n; i++) free(p[i]);
}

/* Allocates n buffers of sizes[i] doubles into p; -1 (all freed, no error set) if one fails. */
static int alloc_all(double** p, const size_t* sizes, int n) {
  for (int i = 0; i < n; i++) p[i] = NULL;
  for (int i = 0; i < n; i++)
    if (!(p[i] = malloc(sizeof(double) * sizes[i]))) return free_all(p, n), -1;
  return 0;
}

/* ---------------------------------------------------------------------------------- */
/* Levenberg-Marquardt                                                                 */

enum { W_QN, W_H, W_HD, W_G, W_RES, W_LOS, W_HIS, W_RQ, W_LM };

static double cost_of(const Core* s, int b, const double* q, const LMArgs* a) {
  double c = 0;
  for (int i = 0; i < s->rows[b]; i++) c += s->r[b][i] * s->r[b][i];
  if (a->posture) {
    double p = 0;
    for (int j = 0; j < s->nfree; j++) {
      double x = q[s->free[j]] - a->nat[j];
      p += a->w[j] * x * x;
    }
    c += a->posture * a->posture * p;
  }
  return c;
}

/* The damped box-QP step from q (buffer set cur) into W[W_RES], the candidate into W[W_QN];
   H and g (the undamped model) stay in W[W_H], W[W_G]. */
static void lm_step(const Core* s, const LMArgs* a, const double* q, int cur, double mu,
                    double** W) {
  int n = s->nfree;
  double *H = W[W_H], *Hd = W[W_HD], *g = W[W_G], *res = W[W_RES];
  double p2 = a->posture * a->posture;
  normal_eq(s->J[cur], s->r[cur], s->rows[cur], n, NULL, n, H, g);
  if (a->posture)
    for (int i = 0; i < n; i++) {
      H[i * n + i] += p2 * a->w[i];
      g[i] += p2 * a->w[i] * (q[s->free[i]] - a->nat[i]);
    }
  double tr = 0;
  for (int i = 0; i < n; i++) tr += H[i * n + i];
  memcpy(Hd, H, sizeof(double) * n * n);
  double damp = mu * (tr / n + 1.0);
  for (int i = 0; i < n; i++) {
    Hd[i * n + i] += damp * a->w[i];
    double qa = q[s->free[i]];
    W[W_LOS][i] = fmax(a->lo[i] - qa, -s->tun.max_step);
    W[W_HIS][i] = fmin(a->hi[i] - qa, s->tun.max_step);
    res[i] = 0.0;
  }
  mju_boxQP(res, W[W_RQ], NULL, Hd, g, n, W[W_LOS], W[W_HIS]);
  step_to(s, q, res, a->lo, a->hi, W[W_QN]);
}

/* The gain ratio of an accepted step: actual over predicted decrease of the model. */
static double lm_rho(int n, double** W, double cost, double cost_new) {
  const double *g = W[W_G], *res = W[W_RES], *H = W[W_H];
  double gr = 0, rHr = 0;
  for (int i = 0; i < n; i++) {
    gr += g[i] * res[i];
    double x = 0;
    for (int j = 0; j < n; j++) x += H[i * n + j] * res[j];
    rHr += res[i] * x;
  }
  double predicted = -(2.0 * gr + rHr);
  return predicted > 0 ? (cost - cost_new) / predicted : 0.0;
}

/* Within the stop fraction (or, for met, within tolerance) and no contact too deep. */
static int lm_within(const Core* s, int b, double stop) {
  return max_norm(s, b) <= stop && s->depth[b] <= 2 * s->tun.collision_tol;
}

/* The iterations of one run from q (evaluated into set 0); fills o->it, o->stop, history. */
static int lm_loop(Core* s, const LMArgs* a, double* q, double** W, RunOut* o, int* curp) {
  int n = s->nfree, cur = 0, stalls = 0;
  double mu = s->tun.mu0, nu = 2.0, cost = cost_of(s, cur, q, a);
  o->stop = STOP_MAX_ITER;
  for (o->it = 1; o->it <= a->max_iter; o->it++) {
    if (lm_within(s, cur, a->stop)) {
      o->stop = STOP_DONE, o->it--;
      break;
    }
    lm_step(s, a, q, cur, mu, W);
    int nxt = 1 - cur;
    if (evaluate(s, W[W_QN], a->collide, nxt)) return -1;
    double cost_new = cost_of(s, nxt, W[W_QN], a);
    if (cost_new < cost) {
      double gain = (cost - cost_new) / cost;
      double rho = lm_rho(n, W, cost, cost_new);
      memcpy(q, W[W_QN], sizeof(double) * s->m->nq);
      cur = nxt;
      cost = cost_new;
      double f = 1.0 - pow(2.0 * rho - 1.0, 3);
      mu = fmax(mu * fmax(1.0 / 3.0, f), 1e-7);
      nu = 2.0;
      o->hist[o->nhist++] = cost;
      double slow = a->posture ? 0.02 : a->early && cost > s->tun.far_cost ? s->tun.far_gain : 1e-3;
      if (gain < slow) {
        stalls++;
        if (a->posture || stalls >= 3) {
          o->stop = a->posture ? STOP_GUIDE_STALL : STOP_STALL;
          break;
        }
      }
      /* Within tolerance already and no longer converging fast: a limit or a contact
         holds a row short of the stop; the polish starts from here. */
      if (!a->posture && a->early && gain < s->tun.met_gain && lm_within(s, cur, 1.0)) {
        o->stop = STOP_MET_SLOW;
        break;
      }
    } else {
      mu *= nu;
      nu *= 2.0;
      o->hist[o->nhist++] = cost;
    }
    double rr = dot(W[W_RES], W[W_RES], n);
    if (mu > 1e3 || rr < 1e-20) {
      o->stop = mu > 1e3 ? STOP_DAMPING : STOP_NO_STEP;
      break;
    }
  }
  if (o->it > a->max_iter) o->it = a->max_iter;
  o->cost = cost;
  *curp = cur;
  return 0;
}

/* One Levenberg-Marquardt run on the constraint and collision rows plus, if posture > 0,
   rows posture * (q - nat) weighted by w (all per free dof), from q (updated in place).
   o->hist needs room for max_iter entries. Returns 0, or -1 with a Python error set. */
int lm_run(Core* s, const LMArgs* a, double* q, RunOut* o) {
  size_t nn = (size_t)(s->nfree ? s->nfree : 1), nq = (size_t)s->m->nq;
  size_t sizes[W_LM] = {nq, nn * nn, nn * nn, nn, nn, nn, nn, nn * (nn + 7)};
  double* W[W_LM];
  int cur = 0, err = -1;
  o->nhist = 0;
  if (alloc_all(W, sizes, W_LM)) return PyErr_NoMemory(), -1;
  if (evaluate(s, q, a->collide, 0)) goto cleanup;
  if (lm_loop(s, a, q, W, o, &cur)) goto cleanup;
  if (o->stop == STOP_DONE) {
    o->done = o->met = 1;
  } else {
    int ok_depth = s->depth[cur] <= 2 * s->tun.collision_tol;
    double mx = max_norm(s, cur);
    o->done = mx <= a->stop && ok_depth;
    o->met = o->done || (mx <= 1.0 && ok_depth);
  }
  err = 0;
cleanup:
  free_all(W, W_LM);
  return err;
}

/* ---------------------------------------------------------------------------------- */
/* The polish toward the most natural posture                                          */

enum {
  P_QN, P_RN0, P_RN1, P_JN0, P_JN1, P_HN, P_GN, P_G, P_B, P_Y, P_STEPM, P_STEP, P_H, P_GG,
  P_RES, P_LOS, P_HIS, P_RQ, P_LOCKED, P_OUT, P_N
};

/* The null-space step over the movable dofs into W[P_STEPM]: it minimises the naturalness
   model (Hn, gn) plus rho |A s|^2 (A: the constraint and collision rows, Gram matrix G), rho
   so large that a direction of A with a singular value over null_tol of their scale is held
   still: the null-space step without a factorisation of A (one Cholesky of nm x nm). A joint
   the step would take out of its range is held too, and the step solved again. Returns
   whether any dof moves. */
static int null_step(const Core* s, const PolishArgs* a, const double* q, double** W) {
  int nm = a->nm;
  const int32_t* mov = a->mov;
  const double *Hn = W[P_HN], *gn = W[P_GN], *G = W[P_G];
  double *B = W[P_B], *y = W[P_Y], *stepm = W[P_STEPM];
  unsigned char *locked = (unsigned char*)W[P_LOCKED], *out = (unsigned char*)W[P_OUT];
  double null_tol = s->tun.null_tol, trg = 0, trn = 0;
  for (int i = 0; i < nm; i++) trg += G[i * nm + i], trn += Hn[i * nm + i];
  double hs = trn / (nm ? nm : 1) + 1e-12;
  double rho = trg > 0 ? hs / (null_tol * null_tol * trg) : 0.0;
  double hold = hs / (null_tol * null_tol);
  memset(locked, 0, nm ? nm : 1);
  for (int pass = 0; pass < 3; pass++) {
    for (int i = 0; i < nm; i++) {
      for (int j = i; j < nm; j++) B[i * nm + j] = B[j * nm + i] = Hn[i * nm + j] + rho * G[i * nm + j];
      B[i * nm + i] += 1e-3 * hs + (locked[i] ? hold : 0.0);
      y[i] = -gn[i];
    }
    mju_cholFactor(B, nm, 0.0);
    mju_cholSolve(stepm, B, y, nm);
    int any = 0;
    for (int i = 0; i < nm; i++) {
      if (locked[i]) stepm[i] = 0.0;
      int f = mov[i];
      double qm = q[s->free[f]] + stepm[i];
      out[i] = (qm < a->lo[f] - 1e-12) || (qm > a->hi[f] + 1e-12);
      if (out[i] && !locked[i]) any = 1;
    }
    if (!any) break;
    for (int i = 0; i < nm; i++)
      if (out[i]) locked[i] = 1;
  }
  int moves = 0;
  for (int i = 0; i < nm; i++) moves |= fabs(stepm[i]) > 1e-12;
  return moves;
}

/* The candidate W[P_QN]: q plus the null step over all free dofs, its largest entry cut to
   radius, inside the bounds. */
static void polish_candidate(const Core* s, const PolishArgs* a, const double* q, double radius,
                             double** W) {
  int n = s->nfree;
  double *step = W[P_STEP], *stepm = W[P_STEPM];
  memset(step, 0, sizeof(double) * n);
  double big = 0;
  for (int i = 0; i < a->nm; i++) {
    step[a->mov[i]] = stepm[i];
    if (fabs(stepm[i]) > big) big = fabs(stepm[i]);
  }
  if (big > radius)
    for (int j = 0; j < n; j++) step[j] *= radius / big;
  step_to(s, q, step, a->lo, a->hi, W[P_QN]);
}

/* Up to two first-order steps of the candidate (buffer set b) back onto the constraints. */
static int back_onto(Core* s, const PolishArgs* a, int b, double** W) {
  int n = s->nfree;
  double *qn = W[P_QN], *H = W[P_H], *res = W[P_RES];
  for (int back = 0; back < 2; back++) {
    int kr = s->rows[b];
    if (!kr || max_norm(s, b) <= a->stop) break;
    normal_eq(s->J[b], s->r[b], kr, n, NULL, n, H, W[P_GG]);
    double trh = 0;
    for (int i = 0; i < n; i++) trh += H[i * n + i];
    for (int i = 0; i < n; i++) {
      H[i * n + i] += 1e-9 * (trh / n + 1.0);
      W[P_LOS][i] = a->lo[i] - qn[s->free[i]];
      W[P_HIS][i] = a->hi[i] - qn[s->free[i]];
      res[i] = 0.0;
    }
    mju_boxQP(res, W[P_RQ], NULL, H, W[P_GG], n, W[P_LOS], W[P_HIS]);
    step_to(s, qn, res, a->lo, a->hi, qn);
    if (evaluate(s, qn, a->collide, b)) return -1;
  }
  return 0;
}

/* The polish iterations from q (evaluated into set 0, natural rows in W[P_RN0], W[P_JN0]). */
static int polish_loop(Core* s, const PolishArgs* a, double* q, double** W, RunOut* o) {
  int n = s->nfree, nrn = s->ne + n + s->npref, cur = 0, stalls = 0;
  int iters = s->tun.natural_iter;
  double nat = dot(W[P_RN0], W[P_RN0], nrn), radius = s->tun.natural_step;
  o->stop = STOP_MAX_ITER;
  for (o->it = 1; o->it <= iters; o->it++) {
    /* Gauss-Newton model of the naturalness, and the constraint rows' Gram matrix */
    normal_eq(W[P_JN0 + cur], W[P_RN0 + cur], nrn, n, a->mov, a->nm, W[P_HN], W[P_GN]);
    normal_eq(s->J[cur], NULL, s->rows[cur], n, a->mov, a->nm, W[P_G], NULL);
    if (!null_step(s, a, q, W)) {
      o->stop = STOP_NO_FREEDOM;
      break;
    }
    polish_candidate(s, a, q, radius, W);
    int nxt = 1 - cur;
    if (evaluate(s, W[P_QN], a->collide, nxt)) return -1;
    if (back_onto(s, a, nxt, W)) return -1;
    if (natural_rows(s, W[P_RN0 + nxt], W[P_JN0 + nxt]) < 0) return -1;
    double nat_new = dot(W[P_RN0 + nxt], W[P_RN0 + nxt], nrn);
    double bound = fmax(a->stop, max_norm(s, cur));
    int ok = max_norm(s, nxt) <= bound && s->depth[nxt] <= fmax(s->depth[cur], 1e-5);
    if (ok && nat_new < nat) {
      double gain = (nat - nat_new) / fmax(nat, 1e-12);
      memcpy(q, W[P_QN], sizeof(double) * s->m->nq);
      cur = nxt;
      nat = nat_new;
      radius = fmin(2.0 * radius, s->tun.max_step);
      stalls = gain < 1e-3 ? stalls + 1 : 0; /* a step that gains under 0.1 % */
    } else {
      radius *= 0.25;
      stalls += radius < 1e-3 ? 1 : 0; /* no step gains, down to a milliradian */
    }
    o->hist[o->nhist++] = dot(s->r[cur], s->r[cur], s->rows[cur]);
    if (stalls >= 2) {
      o->stop = STOP_POLISHED;
      break;
    }
  }
  if (o->it > iters) o->it = iters;
  o->cost = nat;
  return 0;
}

/* The most natural posture among those that meet the constraints, from q (updated in
   place) that meets them; see Solver._polish. o->hist needs room for natural_iter entries.
   Returns 0, or -1 with a Python error set. */
int polish_run(Core* s, const PolishArgs* a, double* q, RunOut* o) {
  size_t nn = (size_t)(s->nfree ? s->nfree : 1), mm = (size_t)(a->nm ? a->nm : 1);
  size_t nrn = (size_t)(s->ne + s->nfree + s->npref) + 1;
  size_t sizes[P_N] = {(size_t)s->m->nq, nrn, nrn, nrn * nn, nrn * nn, mm * mm, mm, mm * mm,
                       mm * mm, mm, mm, nn, nn * nn, nn, nn, nn, nn, nn * (nn + 7), mm, mm};
  double* W[P_N];
  int err = -1;
  o->nhist = 0, o->it = 0, o->cost = 0.0, o->stop = STOP_MAX_ITER;
  if (alloc_all(W, sizes, P_N)) return PyErr_NoMemory(), -1;
  if (evaluate(s, q, a->collide, 0)) goto cleanup;
  if (natural_rows(s, W[P_RN0], W[P_JN0]) < 0) goto cleanup;
  if (polish_loop(s, a, q, W, o)) goto cleanup;
  err = 0;
cleanup:
  free_all(W, P_N);
  return err;
}
