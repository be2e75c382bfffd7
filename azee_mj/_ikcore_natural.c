/* Naturalness rows: gravity torques (effort), comfort, and the preferences' rows (see
   azee_mj/natural.py). See _ikcore_shared.h. */
#include "_ikcore_shared.h"

/* tau (ne,) gravity torque each dof in edof holds, and, if J, its derivative (ne, ncols)
   with respect to qpos[cols]; anc[k * nv + i]: dof k is dof i or one of its ancestors. */
void effort(const mjModel* m, const mjData* d, int ne, const int* edof,
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

/* Naturalness rows (ne effort, nfree comfort, npref preferences) and their Jacobian over
   the free dofs, on the posture in d (after evaluate). Returns the row count or -1. */
int natural_rows(Core* s, double* rn, double* Jn) {
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
  if (s->npref && s->pref_cb) {
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
