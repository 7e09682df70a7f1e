/* gcpush/field.h -- magnetic and electric field models.
 *
 * A field is a `struct gcp_field` whose `type` (one `const struct
 * gcp_field_type` per model, one file per model in fields/) evaluates B,
 * grad B and E on demand.  The block form evaluates B (and E only when the
 * caller passes E arrays) for a struct-of-arrays block of positions; the
 * scene picks the model once, the inner loop never asks which model it is.
 *
 * SI units: x [m], t [s], B [T], grad B [T/m], E [V/m].
 * Field code never exits the process, never includes hdf5.h or mpi.h.
 */
#ifndef GCPUSH_FIELD_H
#define GCPUSH_FIELD_H

#include <stddef.h>
#include <stdint.h>

#include "units.h"
#include "api.h"
GCP_API_BEGIN

#ifdef __cplusplus
extern "C" {
#endif

struct gcp_error;   /* error message buffer, see error.h */
struct gcp_point_B; /* a closed-form field, see field_kernels.h */

/* What a caller asks a field for (bit set in gcp_field_sample.need). */
enum gcp_field_need {
    GCP_NEED_B = 1u,     /* B */
    GCP_NEED_GRADB = 2u, /* grad B tensor dB_i/dx_j */
    GCP_NEED_E = 4u      /* E */
};

struct gcp_field_sample {
    unsigned need;       /* [in] GCP_NEED_* bits the caller wants */
    double B[3];         /* [T] magnetic field */
    double gradB[3][3];  /* [T/m] gradB[i][j] = dB_i / dx_j (only with GCP_NEED_GRADB) */
    double E[3];         /* [V/m] electric field (only with GCP_NEED_E; zero if the model has none) */
};

/* User callback for a field gcpush does not know: fill what out->need asks,
 * return 0, or a particle status (GCP_LEFT_GRID, GCP_LEFT_DOMAIN, ...) when
 * x is outside the field's domain. */
typedef int (*gcp_field_eval_fn)(double t, const double x[3], struct gcp_field_sample *out,
                                 void *ctx);

struct gcp_field;

/* What a model can give: capability bits.  gcp_field_type.caps lists what
 * the model can give at most; gcp_field_caps(f) what this field instance
 * gives (a dipole without corotation has no E, a grid without psi no psi).
 * Code outside fields/ asks these bits, never which model it has. */
enum gcp_field_cap {
    GCP_CAP_B = 1u << 0,        /* B (every model) */
    GCP_CAP_GRADB = 1u << 1,    /* grad B tensor */
    GCP_CAP_E = 1u << 2,        /* a non-zero electric field */
    GCP_CAP_A = 1u << 3,        /* vector potential A and dA (type->potential), phi */
    GCP_CAP_PSI = 1u << 4,      /* poloidal flux psi = R A_phi (type->psi) */
    GCP_CAP_TIME = 1u << 5,     /* B or E depends on t */
    GCP_CAP_AXISYM = 1u << 6,   /* symmetric about the z axis */
    GCP_CAP_DIPOLE_L = 1u << 7, /* centred dipole: McIlwain L = r/(R_E cos^2 lat) and the
                                   surface field B0 (type->dipole_B0) are its magnetic coordinates */
    GCP_CAP_UNIFORM = 1u << 8   /* B and E the same everywhere and at all times (the exact
                                   motion of gcp_exact_uniform, sweep.h, applies) */
};

/* Struct-of-arrays outputs of a block evaluation: n entries per array.
 * Only the arrays the need bits ask for are touched (others may be NULL). */
struct gcp_field_soa {
    double *B[3];    /* [T] Bx, By, Bz (GCP_NEED_B) */
    double *G[3][3]; /* [T/m] G[i][j][k] = dB_i/dx_j at point k (GCP_NEED_GRADB) */
    double *E[3];    /* [V/m] Ex, Ey, Ez (GCP_NEED_E; zeros where the field has none) */
};

/* One run-file key of a model (see fields/README.md and src/run/field_keys.c):
 * the run layer reads the keys a model declares, with their units, and hands
 * the plain values to the model's `build`. */
enum gcp_field_key_kind {
    GCP_KEY_QUANTITY, /* one number with a unit of `quantity` (enum gcp_quantity) */
    GCP_KEY_VECTOR,   /* three numbers with one unit */
    GCP_KEY_FLAG,     /* yes/no */
    GCP_KEY_STRING    /* text (a file name, a choice) */
};
struct gcp_field_key {
    const char *name;     /* run-file key */
    int kind;             /* enum gcp_field_key_kind */
    int quantity;         /* enum gcp_quantity of QUANTITY and VECTOR keys */
    int required;         /* [bool] */
    double def[3];        /* default of a QUANTITY, VECTOR or FLAG key that is not required */
    const char *def_text; /* default of a STRING key (NULL: empty) */
    const char *doc;      /* one line for --help */
};
#define GCP_FIELD_MAX_KEYS 8
#define GCP_FIELD_TEXT_MAX 1024
struct gcp_grid_data; /* grid.h */
/* Reads the grid file `path` into *d (malloc'ed arrays, gcp_grid_data_free):
 * 0, or a negative code with err naming the file and what is wrong.  Field
 * code reads no grid files itself (no HDF5 below the io layer): the caller
 * hands one in, gcp_grid_read (grid_file.h) for gcpush's HDF5 format. */
typedef int (*gcp_grid_reader)(const char *path, struct gcp_grid_data *d,
                               struct gcp_error *err);
/* The values of a model's keys, index for index with its key table. */
struct gcp_field_args {
    double v[GCP_FIELD_MAX_KEYS][3];              /* QUANTITY (v[k][0]), VECTOR, FLAG (0/1) [SI] */
    char text[GCP_FIELD_MAX_KEYS][GCP_FIELD_TEXT_MAX]; /* STRING values */
    int given[GCP_FIELD_MAX_KEYS];                /* [bool] the run file set key k */
    int bad_key;                                  /* [out] key a build error is about (-1: none) */
    gcp_grid_reader grid_read;                    /* [in] reads a `grid` model's file (NULL:
                                                     none; that model then refuses its file) */
};

struct gcp_field_type {
    const char *name; /* run-file name: "uniform", "dipole", ... */
    const char *doc;  /* one line for --help */
    /* Scalar evaluation at one point: fills what s->need asks; returns 0 or
     * a particle status code (enum gcp_status) for points outside the domain. */
    int (*eval)(const struct gcp_field *f, double t, const double x[3],
                struct gcp_field_sample *s);
    /* Block evaluation of B (and E when Ex != NULL) at n points; status[i]
     * is set non-zero only for points outside the field's domain (status
     * may be NULL for models that are defined everywhere). */
    void (*eval_block)(const struct gcp_field *f, double t, size_t n, const double *x,
                       const double *y, const double *z, double *Bx, double *By, double *Bz,
                       double *Ex, double *Ey, double *Ez, int32_t *status);
    /* Frees params (may be NULL when params needs only free()). */
    void (*destroy)(void *params);
    /* ---- the complete interface (issue 12); NULL members fall back ---- */
    unsigned caps; /* GCP_CAP_* the model can give */
    /* Block evaluation with need bits (GCP_NEED_*, grad B included) over
     * struct-of-arrays points; status as in eval_block.  Bit-identical to
     * eval point by point.  NULL: gcp_field_eval_soa loops over eval. */
    void (*eval_soa)(const struct gcp_field *f, double t, unsigned need, size_t n,
                     const double *x, const double *y, const double *z,
                     const struct gcp_field_soa *out, int32_t *status);
    /* Vector potential A [T m], dA[i][j] = dA_i/dx_j [T] (dA may be NULL)
     * and electrostatic potential phi [V] (E = -grad phi; may be NULL).
     * 0, or GCP_ERR_UNKNOWN where the model has none.  (GCP_CAP_A) */
    int (*potential)(const struct gcp_field *f, double t, const double x[3], double A[3],
                     double dA[3][3], double *phi);
    /* Poloidal flux psi = R A_phi [T m^2] at x: 0, a particle status
     * outside the domain, or GCP_ERR_STATE where the field has none.  (GCP_CAP_PSI) */
    int (*psi)(const struct gcp_field *f, const double x[3], double *psi);
    /* Centred-dipole models: the equatorial surface field B0 [T] that, with
     * L = r/(R_E cos^2 lat), gives B_eq = B0/L^3.  (GCP_CAP_DIPOLE_L) */
    double (*dipole_B0)(const struct gcp_field *f);
    /* Run-file keys (NULL-name terminated, at most GCP_FIELD_MAX_KEYS) and
     * the constructor from their values: 0, or a negative code with err set
     * (args->bad_key names the key at fault).  NULL: not a run-file model. */
    const struct gcp_field_key *keys;
    int (*build)(struct gcp_field_args *args, struct gcp_field **out, struct gcp_error *err);
    /* Optional: 1 with *out filled when this field instance is exactly one
     * closed form of field_kernels.h (static, defined everywhere, the same
     * numbers as eval bit for bit), else 0.  Pushers fuse their step
     * around the form's inline kernel; they never ask which model it is. */
    int (*point_B)(const struct gcp_field *f, struct gcp_point_B *out);
};

struct gcp_field {
    const struct gcp_field_type *type;
    void *params;       /* the model's parameters, owned by the field */
    int has_E;          /* [bool] the model has a non-zero electric field */
    int time_dependent; /* [bool] B or E depends on t */
    int axisymmetric;   /* [bool] symmetric about the z axis (dipole, mirror, tokamak) */
    double r_inner;     /* [m] a particle with |x| < r_inner is PRECIPITATED (0: none) */
    double r_outer;     /* [m] a particle with |x| > r_outer has LEFT_DOMAIN (inf: none) */
    double z_max;       /* [m] a particle with |z| > z_max has LEFT_DOMAIN (inf: none) */
    unsigned caps_off;  /* GCP_CAP_* of the type this instance lacks (a grid without psi) */
};

#ifndef GCP_PI
#define GCP_PI 3.14159265358979323846 /* pi (M_PI is not ISO C) */
#endif

/* The Earth's constants (GCP_EARTH_RADIUS, GCP_EARTH_B0, GCP_EARTH_OMEGA)
 * live in units.h, below the fields layer (the RE unit needs the radius). */

/* Built-in models. */
extern const struct gcp_field_type gcp_field_uniform;
extern const struct gcp_field_type gcp_field_mirror;
extern const struct gcp_field_type gcp_field_dipole;
extern const struct gcp_field_type gcp_field_tokamak;
extern const struct gcp_field_type gcp_field_callback;

/* The model called `name`, or NULL. */
const struct gcp_field_type *gcp_field_type_lookup(const char *name);
/* NULL-terminated list of all built-in models (for --help). */
const struct gcp_field_type *const *gcp_field_types(void);

/* gcp_field_from_section, the run-file reader of [field], is the run
 * layer's (run.h): each model only declares its keys and builds. */

/* Direct constructors for library users (SI).  Each returns NULL only when
 * out of memory. */
struct gcp_field *gcp_field_uniform_create(const double B[3], const double E[3]);
/* Vacuum magnetic bottle from the scalar potential
 *   Phi = B0 (z + z^3/(3 Lm^2) - r^2 z/(2 Lm^2)),  B = grad Phi:
 *   Bz = B0 (1 + (z^2 - r^2/2)/Lm^2),  Br = -B0 r z / Lm^2.
 * Exactly curl- and divergence-free; on-axis mirror ratio 1 + z^2/Lm^2. */
struct gcp_field *gcp_field_mirror_create(double B0, double Lm, double z_max, double r_max);
/* Earth's centred dipole, moment along -z (B points north at the equator):
 *   B = B0 R_E^3 [3 (m.rhat) rhat - m] / r^3.
 * corotation != 0 adds the corotation electric field E = -(Omega x r) x B. */
struct gcp_field *gcp_field_dipole_create(double B0, int corotation, double r_inner,
                                          double r_outer);
/* Analytic axisymmetric tokamak of major radius R0, minor radius a, field
 * B0 on axis and safety factor profile q(r) = q0 + (qa - q0) (r/a)^2. */
struct gcp_field *gcp_field_tokamak_create(double B0, double R0, double a, double q0, double qa);
/* A user callback field. */
struct gcp_field *gcp_field_callback_create(gcp_field_eval_fn fn, void *ctx, int has_E);

void gcp_field_free(struct gcp_field *f);

/* Scalar evaluation (dispatches to f->type->eval). */
int gcp_field_eval(const struct gcp_field *f, double t, const double x[3],
                   struct gcp_field_sample *s);

/* What this field gives: type->caps less caps_off, with E, TIME and AXISYM
 * from has_E, time_dependent and axisymmetric. */
unsigned gcp_field_caps(const struct gcp_field *f);

/* Block evaluation with need bits (type->eval_soa, or eval per point). */
void gcp_field_eval_soa(const struct gcp_field *f, double t, unsigned need, size_t n,
                        const double *x, const double *y, const double *z,
                        const struct gcp_field_soa *out, int32_t *status);
void gcp_field_eval_soa_generic(const struct gcp_field *f, double t, unsigned need, size_t n,
                                const double *x, const double *y, const double *z,
                                const struct gcp_field_soa *out, int32_t *status);

/* Vector potential (type->potential): see there.  GCP_ERR_UNKNOWN without one. */
int gcp_field_potential(const struct gcp_field *f, double t, const double x[3], double A[3],
                        double dA[3][3], double *phi);

/* The closed form of f (type->point_B): 1 with *out filled, or 0 (none;
 * out->form = GCP_POINT_B_NONE). */
int gcp_field_point_B(const struct gcp_field *f, struct gcp_point_B *out);

/* Centred-dipole surface field B0 [T] of a GCP_CAP_DIPOLE_L field, else 0. */
double gcp_field_dipole_B0(const struct gcp_field *f);

/* The run-file model names, space separated, into buf (for messages). */
const char *gcp_field_model_names(char *buf, size_t size);

/* Generic block evaluation via the scalar eval, for models without their own. */
void gcp_field_eval_block_generic(const struct gcp_field *f, double t, size_t n,
                                  const double *x, const double *y, const double *z, double *Bx,
                                  double *By, double *Bz, double *Ex, double *Ey, double *Ez,
                                  int32_t *status);

/* Curl-free axisymmetric fields (dipole, mirror): the flux function
 * psi = R A_phi [T m^2] (B_R = -(1/R) dpsi/dZ, B_Z = (1/R) dpsi/dR) and the
 * magnetic scalar potential chi [T m] (B = -grad chi) at x [m].  0, or
 * GCP_ERR_UNKNOWN when the model has no such pair (a field with currents,
 * a 3-D field, a callback); psi and chi are then untouched.  Used by the
 * curl-free canonical chart of the symplectic guiding-centre methods. */
int gcp_field_flux_potential(const struct gcp_field *f, const double x[3], double *psi,
                             double *chi);
/* The same at n points (R[k], 0, Z[k]) of the y = 0 half plane, the same
 * numbers point by point (the dipole's as one vectorised loop). */
int gcp_field_flux_potential_rz(const struct gcp_field *f, size_t n, const double *R,
                                const double *Z, double *psi, double *chi);

#ifdef __cplusplus
}
#endif
GCP_API_END
#endif /* GCPUSH_FIELD_H */
