/*
 * World-side kernels of the native SIL (built by agnav_host/sil/_kernels.py into
 * build/sil/libagnav_world.so; the Python fallback computes the same thing with numpy).
 *
 * agnav_sonar_cast: one sonar trigger group, n sensors of k rays each. cs[] and sn[] hold the
 * cosines and sines (computed by numpy) of the n*k ray angles followed by the n sensor bearings
 * b[i]: sensor i sits at (x + R cos b[i], y + R sin b[i]) and its rays leave there along the
 * unit vectors (cs[i*k + j], sn[i*k + j]). Every ray is intersected
 * with every segment (x0, y0, x1, y1) and circle (cx, cy, r); a ray's range is its nearest hit
 * (inf beyond max_range), a sensor's the nearest of its rays. The arithmetic is the numpy form's
 * (agnav_host.sim._raycast.RayBundle) operation for operation, in IEEE double without
 * contraction (-ffp-contract=off), so the results are the same to the last bit.
 */
#include <math.h>
#include <stdint.h>

void agnav_sonar_cast(int n, int k, double px, double py, double mount_r, const double *cs, const double *sn,
                      int ns, const double *seg, int nc, const double *circ, double max_range, double *out)
{
    for (int i = 0; i < n; i++) {
        const double x = px + mount_r * cs[n * k + i], y = py + mount_r * sn[n * k + i];
        double sensor = INFINITY;
        for (int j = 0; j < k; j++) {
            const double ddx = cs[i * k + j], ddy = sn[i * k + j];
            double best = INFINITY;
            for (int s = 0; s < ns; s++) {
                const double *g = seg + 4 * s;
                const double ex = g[2] - g[0], ey = g[3] - g[1];
                const double qx = g[0] - x, qy = g[1] - y;
                const double den = ddx * ey - ddy * ex;
                const double t = (qx * ey - qy * ex) / den;
                const double u = (qx * ddy - qy * ddx) / den;
                /* den == 0: u is +-inf or NaN and fails the test */
                if (t >= 0.0 && u >= 0.0 && u <= 1.0 && t < best) {
                    best = t;
                }
            }
            for (int c = 0; c < nc; c++) {
                const double *g = circ + 3 * c;
                const double wx = x - g[0], wy = y - g[1], r = g[2];
                const double bb = ddx * wx + ddy * wy;
                const double cc = wx * wx + wy * wy - r * r;
                const double disc = bb * bb - cc;
                if (disc >= 0.0) {
                    const double sq = sqrt(disc);
                    const double t1 = -bb - sq, t2 = -bb + sq;
                    const double t = t1 >= 0.0 ? t1 : (t2 >= 0.0 ? t2 : INFINITY);
                    if (t < best) {
                        best = t;
                    }
                }
            }
            if (best > max_range) {
                best = INFINITY;
            }
            if (best < sensor) {
                sensor = best;
            }
        }
        out[i] = sensor;
    }
}

/*
 * agnav_encoder_edges: the encoder edges of one world step of span_us microseconds from t0_us,
 * queued straight into the firmware through its sil_queue_encoder_edges (queue). Wheel w turned
 * linearly from a0[w] to a1[w] rad; its edge m sits at angle m * step[w] and is crossed at
 * ceil((m * step - a0) / (a1 - a0) * span) microseconds into the step (clipped to 1..span); the
 * levels after it are the quadrature Gray code (mode 0: A leads B forward) or the Hall line
 * (mode 1) of the phase entered, as agnav_host.sim.sensors.WheelEncoder.edges and
 * agnav_host.sil.plant.Plant.advance compute them. Returns the number of edges queued; -2 (and
 * nothing queued) when a wheel has more than cap edges; -1 when the firmware's queue was full.
 */
typedef uint32_t (*queue_edges_fn)(uint8_t idx, const uint64_t *t_us, const uint8_t *ab, uint32_t n);

static const uint8_t QUAD_AB[4] = {0x0, 0x2, 0x3, 0x1};

long agnav_encoder_edges(void *queue, int nw, const double *a0, const double *a1, const double *step, const int *mode,
                         uint64_t t0_us, uint64_t span_us, uint64_t *tbuf, uint8_t *abbuf, uint32_t cap)
{
    queue_edges_fn q = (queue_edges_fn)queue;
    const double span = (double)span_us;
    long total = 0;
    for (int w = 0; w < nw; w++) {
        const int64_t k0 = (int64_t)floor(a0[w] / step[w]);
        const int64_t k1 = (int64_t)floor(a1[w] / step[w]);
        if ((uint64_t)(k1 > k0 ? k1 - k0 : k0 - k1) > cap) {
            return -2;
        }
    }
    for (int w = 0; w < nw; w++) {
        const int64_t k0 = (int64_t)floor(a0[w] / step[w]);
        const int64_t k1 = (int64_t)floor(a1[w] / step[w]);
        if (k1 == k0) {
            continue;
        }
        const int64_t n = k1 > k0 ? k1 - k0 : k0 - k1;
        const int64_t dir = k1 > k0 ? 1 : -1;
        const int64_t first = k1 > k0 ? k0 + 1 : k0;
        const int64_t ph = k1 > k0 ? 0 : -1; /* backwards: crossing boundary m enters phase m - 1 */
        const double da = a1[w] - a0[w];
        for (int64_t j = 0; j < n; j++) {
            const int64_t m = first + dir * j;
            double c = ceil(0.0 + ((double)m * step[w] - a0[w]) / da * span);
            if (c < 1.0) {
                c = 1.0;
            } else if (c > span) {
                c = span;
            }
            tbuf[j] = t0_us + (uint64_t)c;
            const int64_t p = m + ph;
            abbuf[j] = mode[w] == 0 ? QUAD_AB[((p % 4) + 4) % 4] : (uint8_t)((((p % 2) + 2) % 2) << 1);
        }
        if (q((uint8_t)w, tbuf, abbuf, (uint32_t)n) != (uint32_t)n) {
            return -1;
        }
        total += n;
    }
    return total;
}
