/* Collision rows: one per contact deeper than its body pair's floor, from MuJoCo's
   narrowphase on the geom pairs that can move relative to each other. See _ikcore_shared.h. */
#include "_ikcore_shared.h"

/* The penetrating contacts of geom pair (g1, g2) (in the type order of its function) on the
   posture in data, as MuJoCo's narrowphase finds them after mj_collision's bounding-sphere
   test, without the margin: their count, written to pc (mjMAXCONPAIR). */
int penetrations(const mjModel* m, mjData* d, int g1, int g2, mjPreContact* pc) {
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
  double tol = s->tun.collision_tol;
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
      row[j] = x / tol;
    }
    s->r[b][(*rows)++] = (con->dist - fl) / tol;
  }
  return 0;
}

/* MuJoCo's narrowphase on the pair list, in mj_collision's order, only on the pairs that
   can move relative to each other and without the margin: a row (appended to buffer set b
   from *rows on) only for a contact deeper than its floor (<= 0); *depth: the deepest below
   a floor (>= 0). Returns 0, or -1 out of memory. */
int collision_rows(Core* s, int b, int* rows, double* depth) {
  double worst = -INFINITY;
  cluster_spheres(s);
  for (int k = 0; k < s->nrun; k++) {
    int c1 = s->gclu[s->pair[2 * s->run[k]]], c2 = s->gclu[s->pair[2 * s->run[k] + 1]];
    double bound = s->crad[c1] + s->crad[c2];
    if (dist2(s->ccen + 3 * c1, s->ccen + 3 * c2) > bound * bound) continue;
    for (int p = s->run[k]; p < s->run[k + 1]; p++)
      if (pair_rows(s, p, b, rows, &worst)) return -1;
  }
  if (worst > 0) *depth = worst;
  return 0;
}

/* The deepest penetration (>= 0) on the posture in data among geom pairs (n, 2) (each in the
   type order of its function) outside the body pairs this problem lets touch (a floor). */
double deepest(const Core* s, const int32_t* pairs, int n) {
  const mjModel* m = s->m;
  mjPreContact pc[mjMAXCONPAIR];
  double depth = 0.0;
  for (int p = 0; p < n; p++) {
    int g1 = pairs[2 * p], g2 = pairs[2 * p + 1];
    if (s->floor[m->geom_bodyid[g1] * s->nbody + m->geom_bodyid[g2]] != 0.0) continue;
    int k = penetrations(m, s->d, g1, g2, pc);
    for (int c = 0; c < k; c++)
      if (-pc[c].dist > depth) depth = -pc[c].dist;
  }
  return depth;
}

/* The deepest penetration (>= 0) among the contacts mj_collision found in data (contacts
   within the margin only are none), but for those between the bodies of one of the n pairs
   allowed (b1, b2) (both orders listed): what contact_depth in constraints.py computes. */
double contact_depth(const mjModel* m, const mjData* d, const int32_t* allowed, int n) {
  double depth = 0.0;
  for (int i = 0; i < d->ncon; i++) {
    const mjContact* con = d->contact + i;
    if (!(con->dist < 0.0) || !(-con->dist > depth)) continue;
    int b1 = m->geom_bodyid[con->geom[0]], b2 = m->geom_bodyid[con->geom[1]], skip = 0;
    for (int k = 0; k < n && !skip; k++) skip = allowed[2 * k] == b1 && allowed[2 * k + 1] == b2;
    if (!skip) depth = -con->dist;
  }
  return depth;
}

/* The contacts of geom pair (g1, g2) (in the type order of its function) on the posture in
   data as mj_collision finds them: after its bounding-sphere test, with its margin (the
   pair's larger, or the override's), which the narrowphase's result depends on. */
static int margin_contacts(const mjModel* m, mjData* d, int g1, int g2, mjPreContact* pc) {
  double margin = fmax(m->geom_margin[g1], m->geom_margin[g2]);
  if (m->opt.enableflags & mjENBL_OVERRIDE) margin = 0.5 * m->opt.o_margin;
  const double *x1 = d->geom_xpos + 3 * g1, *x2 = d->geom_xpos + 3 * g2;
  double dx = x1[0] - x2[0], dy = x1[1] - x2[1], dz = x1[2] - x2[2];
  double bound = m->geom_rbound[g1] + m->geom_rbound[g2] + margin;
  if (m->geom_rbound[g1] > 0 && m->geom_rbound[g2] > 0 &&
      dx * dx + dy * dy + dz * dz > bound * bound)
    return 0;
  return mjCOLLISIONFUNC[m->geom_type[g1]][m->geom_type[g2]](m, d, pc, g1, g2, margin);
}

/* The deepest penetration (>= 0) on the posture in data among geom pairs (n, 2) (each in the
   type order of its function, as collision_pairs lists them), but between the bodies of one of
   the na pairs allowed (b1, b2) (both orders listed): contact_depth on those pairs alone,
   without mj_collision (a caller that knows the other pairs' depth). */
double pairs_depth(const mjModel* m, mjData* d, const int32_t* pairs, int n,
                   const int32_t* allowed, int na) {
  mjPreContact pc[mjMAXCONPAIR];
  double depth = 0.0;
  for (int p = 0; p < n; p++) {
    int g1 = pairs[2 * p], g2 = pairs[2 * p + 1];
    int k = margin_contacts(m, d, g1, g2, pc), deeper = 0;
    for (int c = 0; c < k; c++) deeper |= -pc[c].dist > depth;
    if (!deeper) continue;
    int b1 = m->geom_bodyid[g1], b2 = m->geom_bodyid[g2], skip = 0;
    for (int i = 0; i < na && !skip; i++) skip = allowed[2 * i] == b1 && allowed[2 * i + 1] == b2;
    if (skip) continue;
    for (int c = 0; c < k; c++)
      if (-pc[c].dist > depth) depth = -pc[c].dist;
  }
  return depth;
}
