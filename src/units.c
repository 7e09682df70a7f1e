/* Quantities with units: "10 MeV" -> 1.602176634e-12 J.
 *
 * Every dimensioned quantity needs its unit; a bare number is refused so a
 * run file never means joules when its author meant MeV. */
#include <ctype.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "gcpush/error.h"
#include "gcpush/particles.h"
#include "gcpush/units.h"

struct unit {
    const char *name;
    double si;              /* value of 1 unit in SI */
    enum gcp_period period; /* time only: a named period instead of seconds */
};

#define EV GCP_E_CHARGE
static const struct unit energy_units[] = {
    {"eV", EV, 0}, {"keV", 1e3 * EV, 0}, {"MeV", 1e6 * EV, 0}, {"GeV", 1e9 * EV, 0},
    {"TeV", 1e12 * EV, 0}, {"J", 1.0, 0}, {NULL, 0, 0}};
static const struct unit length_units[] = {
    {"m", 1.0, 0}, {"cm", 1e-2, 0}, {"mm", 1e-3, 0}, {"km", 1e3, 0},
    {"RE", GCP_EARTH_RADIUS, 0}, {NULL, 0, 0}};
static const struct unit time_units[] = {
    {"s", 1.0, 0}, {"ms", 1e-3, 0}, {"us", 1e-6, 0}, {"ns", 1e-9, 0}, {"min", 60.0, 0},
    {"h", 3600.0, 0}, {"gyro", 1.0, GCP_PERIOD_GYRO}, {"bounce", 1.0, GCP_PERIOD_BOUNCE},
    {"drift", 1.0, GCP_PERIOD_DRIFT}, {NULL, 0, 0}};
static const struct unit bfield_units[] = {
    {"T", 1.0, 0}, {"mT", 1e-3, 0}, {"uT", 1e-6, 0}, {"nT", 1e-9, 0}, {"G", 1e-4, 0},
    {NULL, 0, 0}};
static const struct unit efield_units[] = {
    {"V/m", 1.0, 0}, {"mV/m", 1e-3, 0}, {"kV/m", 1e3, 0}, {"MV/m", 1e6, 0}, {NULL, 0, 0}};
static const struct unit angle_units[] = {
    {"deg", GCP_PI / 180.0, 0}, {"rad", 1.0, 0}, {NULL, 0, 0}};
static const struct unit charge_units[] = {{"e", GCP_E_CHARGE, 0}, {"C", 1.0, 0}, {NULL, 0, 0}};
static const struct unit mass_units[] = {
    {"kg", 1.0, 0}, {"u", GCP_AMU, 0}, {"amu", GCP_AMU, 0}, {"me", GCP_M_ELECTRON, 0},
    {"mp", GCP_M_PROTON, 0}, {NULL, 0, 0}};

static const struct unit *units_of(enum gcp_quantity q)
{
    switch (q) {
    case GCP_Q_ENERGY: return energy_units;
    case GCP_Q_LENGTH: return length_units;
    case GCP_Q_TIME: return time_units;
    case GCP_Q_BFIELD: return bfield_units;
    case GCP_Q_EFIELD: return efield_units;
    case GCP_Q_ANGLE: return angle_units;
    case GCP_Q_CHARGE: return charge_units;
    case GCP_Q_MASS: return mass_units;
    case GCP_Q_NUMBER: break;
    }
    return NULL;
}

const char *gcp_quantity_name(enum gcp_quantity q)
{
    switch (q) {
    case GCP_Q_NUMBER: return "a number";
    case GCP_Q_ENERGY: return "an energy";
    case GCP_Q_LENGTH: return "a length";
    case GCP_Q_TIME: return "a time";
    case GCP_Q_BFIELD: return "a magnetic field";
    case GCP_Q_EFIELD: return "an electric field";
    case GCP_Q_ANGLE: return "an angle";
    case GCP_Q_CHARGE: return "a charge";
    case GCP_Q_MASS: return "a mass";
    }
    return "a quantity";
}

static void list_units(const struct unit *u, char *buf, size_t len)
{
    size_t k = 0;
    buf[0] = '\0';
    for (; u && u->name; u++) {
        int w = snprintf(buf + k, len - k, "%s%s", k ? " " : "", u->name);
        if (w < 0 || (size_t)w >= len - k) break;
        k += (size_t)w;
    }
}

/* Reads numbers from *p (up to max); returns how many, or -1 on a
 * non-finite number. */
static int read_numbers(const char **p, double *v, int max)
{
    int n = 0;
    while (n < max) {
        while (isspace((unsigned char)**p)) (*p)++;
        char *end;
        double d = strtod(*p, &end);
        if (end == *p) break;
        /* "3e" or "1.5x" glued to letters is not a number followed by a unit */
        if (*end && !isspace((unsigned char)*end)) {
            /* allow "4RE"? no: require a space so "1e" typos are caught */
            break;
        }
        if (!isfinite(d)) return -1;
        v[n++] = d;
        *p = end;
    }
    return n;
}

static int parse_unit(const char *p, enum gcp_quantity q, double *scale, enum gcp_period *period,
                      char *why, size_t whylen)
{
    char buf[64];
    while (isspace((unsigned char)*p)) p++;
    size_t n = strlen(p);
    while (n && isspace((unsigned char)p[n - 1])) n--;
    const struct unit *u = units_of(q);
    if (q == GCP_Q_NUMBER) {
        if (n) {
            snprintf(why, whylen, "expected %s without a unit, got '%.*s'", gcp_quantity_name(q),
                     (int)(n > 40 ? 40 : n), p);
            return GCP_ERR_VALUE;
        }
        *scale = 1.0;
        return 0;
    }
    list_units(u, buf, sizeof buf);
    if (n == 0) {
        snprintf(why, whylen, "expected %s with a unit (%s)", gcp_quantity_name(q), buf);
        return GCP_ERR_VALUE;
    }
    for (; u->name; u++) {
        if (strlen(u->name) == n && strncmp(u->name, p, n) == 0) {
            *scale = u->si;
            if (period) *period = u->period;
            return 0;
        }
    }
    snprintf(why, whylen, "expected %s unit (%s), got '%.*s'", gcp_quantity_name(q), buf,
             (int)(n > 40 ? 40 : n), p);
    return GCP_ERR_VALUE;
}

int gcp_parse_quantity(const char *text, enum gcp_quantity q, double *si,
                       enum gcp_period *period, char *why, size_t whylen)
{
    const char *p = text;
    double v;
    if (period) *period = GCP_PERIOD_NONE;
    int n = read_numbers(&p, &v, 1);
    if (n < 0) {
        snprintf(why, whylen, "value is not a finite number");
        return GCP_ERR_VALUE;
    }
    if (n == 0) {
        snprintf(why, whylen, "expected %s, got '%.40s'", gcp_quantity_name(q), text);
        return GCP_ERR_VALUE;
    }
    double scale;
    int rc = parse_unit(p, q, &scale, period, why, whylen);
    if (rc) return rc;
    *si = v * scale;
    if (!isfinite(*si)) {
        snprintf(why, whylen, "value overflows in SI units");
        return GCP_ERR_VALUE;
    }
    return 0;
}

int gcp_parse_vector(const char *text, enum gcp_quantity q, double v[3], char *why,
                     size_t whylen)
{
    const char *p = text;
    double w[3];
    int n = read_numbers(&p, w, 3);
    if (n < 0) {
        snprintf(why, whylen, "a component is not a finite number");
        return GCP_ERR_VALUE;
    }
    if (n != 3) {
        snprintf(why, whylen, "expected three components then a unit, got '%.40s'", text);
        return GCP_ERR_VALUE;
    }
    double scale;
    enum gcp_period period = GCP_PERIOD_NONE;
    int rc = parse_unit(p, q, &scale, &period, why, whylen);
    if (rc) return rc;
    if (period != GCP_PERIOD_NONE) {
        snprintf(why, whylen, "a vector cannot be given in periods");
        return GCP_ERR_VALUE;
    }
    for (int i = 0; i < 3; i++) v[i] = w[i] * scale;
    return 0;
}
