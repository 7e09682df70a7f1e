/* Error messages: the first error wins (later ones are consequences). */
#include <stdarg.h>
#include <stdio.h>

#include "gcpush/error.h"

int gcp_error_set(struct gcp_error *e, int code, const char *fmt, ...)
{
    if (e && e->code == 0) {
        va_list ap;
        va_start(ap, fmt);
        vsnprintf(e->msg, sizeof e->msg, fmt, ap);
        va_end(ap);
        e->code = code;
    }
    return code;
}
