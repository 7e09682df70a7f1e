/* gcpush/units.h -- quantities with units in run files.
 *
 * "10 MeV", "4 RE", "3.12e-5 T", "30 deg", "0.5 mV/m" -> SI doubles.
 * A dimensioned quantity needs its unit: a bare number is an error, never a
 * silent SI default.  Periods ("2 drift", "0.01 gyro") are returned as a
 * multiple of the named period for the scene to resolve.
 */
#ifndef GCPUSH_UNITS_H
#define GCPUSH_UNITS_H

#include <stddef.h>
#include "api.h"
GCP_API_BEGIN

/* Physical constants of the Earth models (fields/dipole.c, igrf.c; the RE unit). */
#ifndef GCP_EARTH_RADIUS
#define GCP_EARTH_RADIUS 6.3712e6    /* R_E [m] (IGRF reference radius) */
#define GCP_EARTH_B0 3.12e-5         /* equatorial surface dipole field [T] */
#define GCP_EARTH_OMEGA 7.2921159e-5 /* Earth's sidereal rotation rate [rad/s] */
#endif

#ifdef __cplusplus
extern "C" {
#endif

enum gcp_quantity {
    GCP_Q_NUMBER,  /* dimensionless, no unit allowed */
    GCP_Q_ENERGY,  /* eV keV MeV GeV TeV J -> [J] */
    GCP_Q_LENGTH,  /* m cm mm km RE -> [m] */
    GCP_Q_TIME,    /* s ms us ns min h -> [s]; also gyro bounce drift periods */
    GCP_Q_BFIELD,  /* T mT uT nT G -> [T] */
    GCP_Q_EFIELD,  /* V/m mV/m kV/m -> [V/m] */
    GCP_Q_ANGLE,   /* deg rad -> [rad] */
    GCP_Q_CHARGE,  /* e C -> [C] */
    GCP_Q_MASS     /* kg u amu me mp -> [kg] */
};

enum gcp_period {
    GCP_PERIOD_NONE = 0, /* an absolute time */
    GCP_PERIOD_GYRO,
    GCP_PERIOD_BOUNCE,
    GCP_PERIOD_DRIFT
};

/* Parses "number unit" (or a bare number for GCP_Q_NUMBER) into SI.
 * For GCP_Q_TIME, *period (may be NULL for other quantities) receives the
 * named period and *si the multiple.  Returns 0, or GCP_ERR_VALUE with a
 * reason in why ("expected an energy unit (eV keV MeV GeV TeV J), got 'm'"). */
int gcp_parse_quantity(const char *text, enum gcp_quantity q, double *si,
                       enum gcp_period *period, char *why, size_t whylen);

/* Parses "a b c unit" (three numbers, one unit after them) into SI. */
int gcp_parse_vector(const char *text, enum gcp_quantity q, double v[3], char *why,
                     size_t whylen);

/* Human name of a quantity ("an energy", "a length", ...) for messages. */
const char *gcp_quantity_name(enum gcp_quantity q);

#ifdef __cplusplus
}
#endif
GCP_API_END
#endif
