/* [integrator] keys of method = hybrid (include/gcpush/hybrid.h):
 *
 *   method       = hybrid
 *   dt           = 0.01 bounce   # the guiding-centre step (and the grid of switch decisions)
 *   gc           = gc-rk4        # any guiding-centre method (default gc-rk4)
 *   fo           = boris         # any full-orbit method (default boris)
 *   switch_to_fo = 0.1           # eps above which a guiding centre becomes a full orbit
 *   switch_to_gc = 0.05          # eps below which a full orbit returns (< switch_to_fo)
 *   fo_dt        = 0.05 gyro     # full-orbit step, of the local gyro-period
 *
 * Defaults: switch_to_fo = 0.1 is the plain guiding-centre methods' NONADIABATIC
 * threshold (first-order GC theory is off by O(eps): ~10% there); switch_to_gc
 * = 0.05 halves it, so a particle whose eps wanders by less than a factor 2
 * around the threshold switches once, not back and forth; fo_dt = 0.05 gyro is
 * 20 Boris steps per gyration (gyrophase error (omega dt)^3/12 = 2.6e-3 rad per
 * gyration, energy exact in a static B). */
#include <stdio.h>
#include <string.h>

#include "gcpush/run.h"
#include "run_priv.h"

static int method_key(struct gcp_section *s, const char *key, const char *dflt,
                      enum gcp_pusher_kind kind, const struct gcp_field *field,
                      const struct gcp_pusher_type **out, struct gcp_error *err)
{
    char name[32];
    int rc = gcp_section_string(s, key, 0, name, sizeof name, err);
    if (rc < 0) return rc;
    if (rc == 0) snprintf(name, sizeof name, "%s", dflt);
    *out = gcp_pusher_lookup(name);
    if (!*out || (*out)->kind != kind) {
        char names[512];
        return gcp_section_error(s, key, err, GCP_ERR_VALUE, "'%s' is not a %s method (of %s)",
                                 name, kind == GCP_GUIDING_CENTRE ? "guiding-centre" : "full-orbit",
                                 gcp_pusher_names(names, sizeof names));
    }
    /* the same refusal as for a plain method: never a run where every particle fails */
    char why[512];
    if ((*out)->applies && (*out)->applies(field, why, sizeof why))
        return gcp_section_error(s, key, err, GCP_ERR_VALUE, "'%s' cannot run in the %s field: %s",
                                 name, field->type->name, why);
    return 0;
}

int gcp_scene_hybrid_keys(struct gcp_scene *sc, struct gcp_section *s, struct gcp_error *err)
{
    struct gcp_hybrid_opts *o = &sc->hybrid_opts;
    int rc;
    if ((rc = method_key(s, "gc", "gc-rk4", GCP_GUIDING_CENTRE, sc->field, &o->gc, err)) < 0 ||
        (rc = method_key(s, "fo", "boris", GCP_FULL_ORBIT, sc->field, &o->fo, err)) < 0)
        return rc;
    o->to_fo = 0.1;
    o->to_gc = 0.05;
    if ((rc = gcp_section_quantity(s, "switch_to_fo", GCP_Q_NUMBER, 0, &o->to_fo, err)) < 0 ||
        (rc = gcp_section_quantity(s, "switch_to_gc", GCP_Q_NUMBER, 0, &o->to_gc, err)) < 0)
        return rc;
    if (!(o->to_fo > 0.0 && o->to_fo < 1e6))
        return gcp_section_error(s, "switch_to_fo", err, GCP_ERR_VALUE,
                                 "must be > 0 (the adiabaticity rho |grad B| / B or rho / R_c "
                                 "above which a guiding centre becomes a full orbit)");
    if (!(o->to_gc > 0.0 && o->to_gc < o->to_fo))
        return gcp_section_error(s, "switch_to_gc", err, GCP_ERR_VALUE,
                                 "must lie in (0, switch_to_fo = %g): the gap is the hysteresis",
                                 o->to_fo);
    o->fo_dt = 0.05;
    enum gcp_period per = GCP_PERIOD_GYRO;
    if ((rc = gcp_section_time(s, "fo_dt", 0, &o->fo_dt, &per, err)) < 0) return rc;
    if (rc == 1 && per != GCP_PERIOD_GYRO)
        return gcp_section_error(s, "fo_dt", err, GCP_ERR_VALUE,
                                 "is a fraction of the local gyro-period: give it in gyro "
                                 "(e.g. 0.05 gyro)");
    if (!(o->fo_dt > 0.0 && o->fo_dt <= 0.25))
        return gcp_section_error(s, "fo_dt", err, GCP_ERR_VALUE,
                                 "must lie in (0, 0.25] gyro (the gyrophase of a step must stay "
                                 "well below pi to be followed)");
    o->seed = sc->seed;
    sc->hybrid = 1;
    sc->pusher = &gcp_pusher_hybrid;
    return 0;
}
