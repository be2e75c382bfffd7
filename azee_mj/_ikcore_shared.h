/* The posture solver's compiled core: shared declarations (see azee_mj/posture/plan.py).

   The core is five files: _ikcore_rows.c (constraint rows), _ikcore_collision.c (collision
   rows and depths), _ikcore_natural.c (naturalness rows), _ikcore_lm.c (the
   Levenberg-Marquardt run and the natural-posture polish) and _ikcore.c (the Python module).

   Python and C share three records, laid out here and mirrored by numpy structured dtypes in
   azee_mj/posture/plan.py (the module's `layout()` reports sizeof/offsetof of each field so
   a test holds the two equal): Block (one constraint's block of rows), Term (a point term of
   a block) and Tunables (the solver's constants, whose only home is Python). Units: metres,
   radians. */
#ifndef AZEE_IKCORE_H
#define AZEE_IKCORE_H

#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include <mujoco/mujoco.h>

enum { B_POINT = 0, B_ORIENT = 1, B_JOINT = 2, B_GENERIC = 3 };
enum { T_SITE = 0, T_BODY = 1 };
/* How a hard constraint's rows give its norm (see hard_norm): as they are, or as the angle
   of an orientation whose rows measure its chord or its sine. */
enum { HARD_LINEAR = 0, HARD_CHORD = 1, HARD_SINE = 2, HARD_RANGE = 4 /* a flag */ };

/* One block of rows, [start, start + k). POINT: site - (c + sum coef_t term_t). ORIENT: body
   axis a = R local against v = (the constant c, value * a body axis, or value * unit(c + sum
   coef_t term_t)), along (3 rows: a - v) or perp (1 row: a . v). JOINT: qpos[id] - value.
   GENERIC: written by the Python callback. */
typedef struct {
  int32_t kind, start, k, hard, perp;
  int32_t id;     /* site (POINT), body (ORIENT), qpos adr (JOINT) */
  int32_t id2;    /* ORIENT: body of the target axis, -1 otherwise */
  int32_t dof;    /* JOINT */
  int32_t t0, nt; /* POINT, ORIENT toward a point: terms [t0, t0 + nt) */
  double c[3];    /* POINT: constant part of the target; ORIENT: constant v or its part */
  double local[3], local2[3];
  double value;   /* JOINT: target; ORIENT: sign of the target axis or point */
} Block;

/* One point term: coef * (site or body origin id). */
typedef struct {
  int32_t kind, id;
  double coef;
} Term;

/* The solver's constants (Python's azee_mj.posture.plan.TUNABLES, given once per Core). */
typedef struct {
  double mu0;           /* first LM damping, relative to the mean diagonal of J^T J */
  double max_step;      /* trust region: largest change of a joint in a step [rad or m] */
  double met_gain;      /* once met, a step gaining less ends the run */
  double far_cost;      /* over this cost ... */
  double far_gain;      /* ... a step gaining less is a stall */
  double collision_tol; /* depth at which a collision row reaches 1 [m] */
  double null_tol;      /* the polish's null-space threshold */
  double natural_step;  /* first trust radius of a polish step [rad] */
  int32_t natural_iter; /* most polish steps */
  int32_t pad_;
  double range_free;    /* a ranged orientation's rows are zero within this fraction of tol */
} Tunables;

/* Why a run stopped (Python's azee_mj.posture.problem.Stop, same order). */
typedef enum {
  STOP_DONE = 0,     /* every constraint within its stop fraction, no contact too deep */
  STOP_MET_SLOW,     /* met, and the last step gained under met_gain */
  STOP_STALL,        /* three steps of little gain */
  STOP_GUIDE_STALL,  /* a step of little gain with the guide on */
  STOP_DAMPING,      /* the damping grew past 1e3: no step lowers the cost */
  STOP_NO_STEP,      /* the step vanished */
  STOP_MAX_ITER,     /* the iteration budget ran out */
  STOP_NO_FREEDOM,   /* polish: no direction left that keeps the constraints */
  STOP_POLISHED,     /* polish: two steps in a row gained nothing worth it */
  STOP_COUNT
} Stop;

typedef struct {
  PyObject_HEAD
  mjModel* m;
  mjData* d;
  PyObject* owner;      /* keeps the model/data Python objects alive */
  PyObject* callback;   /* fills the GENERIC blocks (or None) */
  Py_buffer rbuf, Jbuf; /* raw rows (nrows,) and (nrows, nv), shared with Python */
  Tunables tun;
  int nblock, nrows, nfree, nterm, nv, nbody, has_generic;
  Block* blocks;
  Term* terms;
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
  double* norms[2];
  double depth[2];
  int nhard;
  double* hard; /* (nhard, 4) first row, end row, kind (HARD_*, | HARD_RANGE for a
                   ranged orientation), tolerance: one norm each */
  /* naturalness (set_natural) */
  int ne, npref;
  int* edof;
  double *escale, *comfort, *neutral;
  unsigned char* anc;
  PyObject* pref_cb;
  Py_buffer prbuf, pJbuf;
} Core;

/* One LM run's inputs (all per free dof) and outcome. */
typedef struct {
  const double *lo, *hi, *w, *nat;
  double posture, stop;
  int max_iter, collide, early;
} LMArgs;

/* One polish's inputs (mov: indices into the free dofs) and the outcome of either run. */
typedef struct {
  const double *lo, *hi;
  const int32_t* mov;
  int nm, collide;
  double stop;
} PolishArgs;

typedef struct {
  double cost; /* LM: the cost; polish: the natural cost */
  int it, done, met;
  Stop stop;
  int nhist;
  double* hist; /* (max iterations,) cost after each iteration */
} RunOut;

/* Small vector helpers, inline in every file that uses them. */
static inline void cross3(const double* a, const double* b, double* out) {
  out[0] = a[1] * b[2] - a[2] * b[1];
  out[1] = a[2] * b[0] - a[0] * b[2];
  out[2] = a[0] * b[1] - a[1] * b[0];
}

static inline double dist2(const double* a, const double* b) {
  double x = a[0] - b[0], y = a[1] - b[1], z = a[2] - b[2];
  return x * x + y * y + z * z;
}

/* Room for `need` rows in both buffer sets. Returns 0, or -1 out of memory (no error set). */
static inline int grow(Core* s, int need) {
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

/* _ikcore_rows.c */
int raw_rows(Core* s);
int evaluate(Core* s, const double* q, int collide, int b);
double max_norm(const Core* s, int b);

/* _ikcore_collision.c */
int penetrations(const mjModel* m, mjData* d, int g1, int g2, mjPreContact* pc);
int collision_rows(Core* s, int b, int* rows, double* depth);
double deepest(const Core* s, const int32_t* pairs, int n);
double contact_depth(const mjModel* m, const mjData* d, const int32_t* allowed, int n);
double pairs_depth(const mjModel* m, mjData* d, const int32_t* pairs, int n,
                   const int32_t* allowed, int na);

/* _ikcore_natural.c */
void effort(const mjModel* m, const mjData* d, int ne, const int* edof, const unsigned char* anc,
            int ncols, const int* cols, double* tau, double* J);
int natural_rows(Core* s, double* rn, double* Jn);

/* _ikcore_lm.c: q (nq,) is updated in place; -1 with a Python error set on failure */
int lm_run(Core* s, const LMArgs* a, double* q, RunOut* out);
int polish_run(Core* s, const PolishArgs* a, double* q, RunOut* out);

#endif
