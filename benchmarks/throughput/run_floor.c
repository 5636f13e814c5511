/* The plain-C floor of python -m benchmarks sweep-lanes: a run's rk4 steps for W schemes at once,
   the arithmetic of the kernel's right-hand side (physics/kernel/walk.py's pieces as motion.rhs and
   batched.rhs_lanes call them) and of integrate/rk_lanes.py's step, for the benchmark's trains only:
   the governor on its natural branches, rolling resistance and at most one ASABE draft a cart, the
   level, the steering actuator in closed form. No kink splitting, no switching functions, no trace,
   no guard: the floor under a run's stepping.

   Built twice by the benchmark (sweep_floor.py): W = 1 by gcc -O2 -ffp-contract=off, one scheme at a
   time, whose steps equal rk_lanes.rk_step_lanes_libm's bit for bit (the same operations in the same
   order, IEEE, the C library's functions); W = 8 by gcc -O3 -march=native -fno-math-errno
   -D__FAST_MATH__, the schemes in structure-of-arrays form, one per SIMD lane: IEEE arithmetic in the
   same order, and sin, cos, atan2, tanh, exp from glibc's vector math library (libmvec), which math.h
   declares only under __FAST_MATH__. Two things let gcc vectorise the loops: cos(x + 0.0), so that
   sin and cos of one argument are not merged into sincos (which has no vector form; cos is even, so
   the value is cos(x)), and restrict on the right-hand side's arrays. At most MAXN carts.

   Arrays, the scheme index innermost (W a row): head[NH][W], cart[n][NC][W], y[n + 5][W] (x, y,
   th_1..th_n, psi_1, V, z), commands[ticks][W], v_sets[ticks][W]; drafts[n]: 1 where cart k has a
   draft (the same in every lane). */
#include <math.h>

#ifndef W
#define W 8
#endif
#define MAXN 8
#define LANES for (int j = 0; j < W; j++)

enum { H_TAU, H_MAX_RATE, H_MAX_ANGLE, H_MAX_FORCE, H_MAX_POWER, H_KP, H_KI, H_WINDUP, H_V0, NH };
enum { C_LENGTH, C_LAM, C_LAM2, C_MU2, C_MASS, C_INERTIA, C_ROLLING, C_SOIL, C_A, C_B, C_C, C_WIDTH, C_DEPTH, NC };

static inline double pymin(double a, double b) { return b < a ? b : a; }
static inline double pymax(double a, double b) { return b > a ? b : a; }

/* walk.actuator: psi_1 at T s into a tick that started at psi0 (release > 1e300: the free lag;
   not isinf, which a -ffast-math build would take to be false) */
static inline double actuator(double max_angle, double tau0, double psi0, double command, double max_rate,
                              double release, double T) {
    double target = pymin(pymax(command, -max_angle), max_angle);
    int free_ = release > 1e300, limited = T <= release;
    double sign = target > psi0 ? 1.0 : -1.0;
    double tau = (limited && !free_) ? 1.0 : tau0;
    double e = exp(free_ ? -T / tau : (limited ? 0.0 : -(T - release) / tau));
    return free_ ? target + (psi0 - target) * e
                 : (limited ? psi0 + sign * max_rate * T : target - sign * tau0 * max_rate * e);
}

/* motion.rhs on these trains: y' of W schemes into dy */
static void rhs(int n, const int *restrict drafts, const double *restrict hd, const double *restrict ct,
                const double *restrict y, const double *restrict cmd, const double *restrict vset, double *restrict dy) {
    double kv[W], kd[W], pv[W], pd[W], trp[W], bdp[W], mass[W], mrate[W], q[W];
    const double *psi1 = y + (n + 2) * W, *V = y + (n + 3) * W, *z = y + (n + 4) * W;
    LANES {
        double target = pymin(pymax(cmd[j], -hd[H_MAX_ANGLE * W + j]), hd[H_MAX_ANGLE * W + j]);
        double linear = (target - psi1[j]) / hd[H_TAU * W + j];
        double mr = hd[H_MAX_RATE * W + j];
        pd[j] = pymin(pymax(linear, -mr), mr);
        kv[j] = 1.0, kd[j] = 0.0, pv[j] = psi1[j], trp[j] = 0.0, bdp[j] = 0.0;
        mass[j] = 0.0, mrate[j] = 0.0, q[j] = 0.0;
    }
    for (int k = 0; k < n; k++) {
        const double *c = ct + k * NC * W;
        const double *th = y + (2 + k) * W, *th_next = y + (3 + k) * W;
        int last = k == n - 1, draft = drafts[k];
        LANES {
            double l = c[C_LENGTH * W + j];
            double s = sin(pv[j]), co = cos(pv[j] + 0.0);
            double t_val = kv[j] * s / l;                                   /* kinematics */
            double theta_rate = t_val * V[j];
            double p_dot = k == 0 ? pd[j] : trp[j] - theta_rate - bdp[j];
            double s_dot = co * p_dot, c_dot = -s * p_dot, b_val = kv[j] * co;
            double mu2 = c[C_MU2 * W + j], m = c[C_MASS * W + j], J = c[C_INERTIA * W + j];
            double t_dot = (kd[j] * s + kv[j] * s_dot) / l;                  /* inertia */
            double rc = sqrt(co * co + mu2 * s * s);
            double rc_dot = (co * c_dot + mu2 * s * s_dot) / rc;
            double kc = kv[j] * rc, kc_dot = kd[j] * rc + kv[j] * rc_dot;
            mass[j] += m * kc * kc + J * t_val * t_val;
            mrate[j] += 2.0 * (m * kc * kc_dot + J * t_val * t_dot);
            double axle = b_val * V[j];                                      /* resistance */
            double total = c[C_ROLLING * W + j] * 1.0;
            if (draft) {
                double S = fabs(axle) * 3.6;
                total += c[C_SOIL * W + j] * (c[C_A * W + j] + c[C_B * W + j] * S + c[C_C * W + j] * S * S)
                         * c[C_WIDTH * W + j] * c[C_DEPTH * W + j];
            }
            q[j] += total * tanh(axle / hd[H_V0 * W + j]) * b_val;
            dy[(2 + k) * W + j] = theta_rate;
            if (!last) {                                                     /* next_link */
                double lam = c[C_LAM * W + j], lam2 = c[C_LAM2 * W + j];
                double rl2 = co * co + lam2 * s * s, rl = sqrt(rl2);
                double rl_dot = (co * c_dot + lam2 * s * s_dot) / rl;
                double k_next = kv[j] * rl, kd_next = kd[j] * rl + kv[j] * rl_dot;
                pv[j] = th[j] - th_next[j] - atan2(lam * s, co);
                bdp[j] = lam * p_dot / rl2;
                kv[j] = k_next, kd[j] = kd_next, pd[j] = p_dot, trp[j] = theta_rate;
            }
        }
    }
    LANES {
        double error = vset[j] - V[j];                                       /* governor */
        double u = hd[H_KP * W + j] * error + z[j];
        double speed = pymax(fabs(V[j]), 0.1);
        double limit = pymin(hd[H_MAX_FORCE * W + j], hd[H_MAX_POWER * W + j] / speed);
        double traction = pymin(pymax(u, -limit), limit);
        double rate = hd[H_KI * W + j] * error + (traction - u) / hd[H_WINDUP * W + j];
        double accel = (traction - q[j] - 0.5 * mrate[j] * V[j]) / mass[j];
        double h = y[2 * W + j] + psi1[j];                                   /* course */
        double s = sin(h), co = cos(h + 0.0);
        dy[j] = V[j] * co, dy[W + j] = V[j] * s;
        double target = pymin(pymax(cmd[j], -hd[H_MAX_ANGLE * W + j]), hd[H_MAX_ANGLE * W + j]);
        double mr = hd[H_MAX_RATE * W + j];
        dy[(n + 2) * W + j] = pymin(pymax((target - psi1[j]) / hd[H_TAU * W + j], -mr), mr);
        dy[(n + 3) * W + j] = accel, dy[(n + 4) * W + j] = rate;
    }
}

/* rk_lanes.rk_step_lanes with rk4 and the actuator in closed form: y stepped by h in place; psi0,
   release per lane as the tick began */
static void rk4_step(int n, const int *drafts, const double *hd, const double *ct, double *y, const double *cmd,
                     const double *vset, const double *release, double h) {
    static const double node[4] = {0.0, 0.5, 0.5, 1.0};
    const int size = n + 5, ip = n + 2;
    double K[4][(MAXN + 5) * W], tmp[(MAXN + 5) * W], psi0[W];
    LANES psi0[j] = y[ip * W + j];
    rhs(n, drafts, hd, ct, y, cmd, vset, K[0]);
    for (int i = 1; i < 4; i++) {
        double scale = h / (i == 3 ? 1.0 : 2.0);
        for (int m = 0; m < size; m++)
            LANES tmp[m * W + j] = y[m * W + j] + scale * (1.0 * K[i - 1][m * W + j]);
        LANES tmp[ip * W + j] = actuator(hd[H_MAX_ANGLE * W + j], hd[H_TAU * W + j], psi0[j], cmd[j],
                                         hd[H_MAX_RATE * W + j], release[j], node[i] * h);
        rhs(n, drafts, hd, ct, tmp, cmd, vset, K[i]);
    }
    double scale = h / 6.0;
    for (int m = 0; m < size; m++)
        LANES y[m * W + j] = y[m * W + j] + scale * (1.0 * K[0][m * W + j] + 2.0 * K[1][m * W + j]
                                                     + 2.0 * K[2][m * W + j] + 1.0 * K[3][m * W + j]);
    LANES y[ip * W + j] = actuator(hd[H_MAX_ANGLE * W + j], hd[H_TAU * W + j], psi0[j], cmd[j],
                                   hd[H_MAX_RATE * W + j], release[j], h);
}

/* One rk4 step of a batch of `lanes` schemes (a multiple of W), each W-wide block on its own. */
void step(int n, const int *drafts, const double *head, const double *cart, double *y, const double *cmd,
          const double *vset, const double *release, double h, long lanes) {
    for (long b = 0; b < lanes / W; b++) {
        rk4_step(n, drafts, head + b * NH * W, cart + b * n * NC * W, y + b * (n + 5) * W, cmd + b * W,
                 vset + b * W, release + b * W, h);
    }
}

/* A run: `ticks` rk4 steps of h, tick i holding commands[i], v_sets[i], each tick's actuator release
   from its start (rk.actuator_release); the batch as in `step`, inputs [block][ticks][W]. */
void run(int n, const int *drafts, const double *head, const double *cart, double *y, const double *commands,
         const double *v_sets, double h, long ticks, long lanes) {
    for (long b = 0; b < lanes / W; b++) {
        const double *hd = head + b * NH * W, *ct = cart + b * n * NC * W;
        double *yb = y + b * (n + 5) * W;
        for (long i = 0; i < ticks; i++) {
            const double *cmd = commands + (b * ticks + i) * W;
            double release[W];
            LANES {
                double max_angle = hd[H_MAX_ANGLE * W + j], tau = hd[H_TAU * W + j], mr = hd[H_MAX_RATE * W + j];
                double target = pymin(pymax(cmd[j], -max_angle), max_angle);
                double gap = fabs(target - yb[(n + 2) * W + j]);
                release[j] = !(gap / tau > mr) ? INFINITY : (gap - tau * mr) / mr;
            }
            rk4_step(n, drafts, hd, ct, yb, cmd, v_sets + (b * ticks + i) * W, release, h);
        }
    }
}
