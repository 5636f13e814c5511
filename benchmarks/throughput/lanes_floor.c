/* The C floor of python -m benchmarks lanes: the same loops over lanes as physics/kernel/vmath.py's
   *_lanes, compiled by gcc -O3 -ffast-math for this CPU, which calls glibc's vector math library
   (libmvec: _ZGV* entries, four or eight doubles a call) when its math.h declares them. */
#include <math.h>

void sincos_lanes(const double *x, double *s, double *c, long n) {
    for (long j = 0; j < n; j++) { s[j] = sin(x[j]); c[j] = cos(x[j]); }
}
void atan2_lanes(const double *y, const double *x, double *out, long n) {
    for (long j = 0; j < n; j++) out[j] = atan2(y[j], x[j]);
}
void exp_lanes(const double *x, double *out, long n) {
    for (long j = 0; j < n; j++) out[j] = exp(x[j]);
}
void tanh_lanes(const double *x, double *out, long n) {
    for (long j = 0; j < n; j++) out[j] = tanh(x[j]);
}
