/* gcpush/error.h -- error codes and messages.
 *
 * Library functions return 0 or a negative enum gcp_errcode and fill a
 * struct gcp_error whose message names file, line and key where there is
 * one ("runs/x.run:12: [particles] energy: expected an energy ...").
 * Nothing in the library exits the process.
 */
#ifndef GCPUSH_ERROR_H
#define GCPUSH_ERROR_H
#include "api.h"
GCP_API_BEGIN

#ifdef __cplusplus
extern "C" {
#endif

enum gcp_errcode {
    GCP_OK = 0,
    GCP_ERR_NOMEM = -1,   /* out of memory */
    GCP_ERR_IO = -2,      /* a file could not be read or written */
    GCP_ERR_SYNTAX = -3,  /* run file syntax */
    GCP_ERR_VALUE = -4,   /* a value, unit or range that does not fit */
    GCP_ERR_UNKNOWN = -5, /* an unknown section, key or name */
    GCP_ERR_MISSING = -6, /* a required key is missing */
    GCP_ERR_HDF5 = -7,    /* the HDF5 library failed */
    GCP_ERR_MPI = -8,     /* MPI failed */
    GCP_ERR_STATE = -9    /* a call out of order or an unsupported combination */
};

struct gcp_error {
    int code;        /* enum gcp_errcode of the first error, 0 when none */
    char msg[1024];  /* one line, no trailing newline */
};

/* Sets e (when e != NULL and no error is recorded yet) and returns code. */
int gcp_error_set(struct gcp_error *e, int code, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 3, 4)))
#endif
    ;

#ifdef __cplusplus
}
#endif
GCP_API_END
#endif
