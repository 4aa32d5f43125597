/* The inner loop of dea_opt.mesh.walk.Walker.follow, the pass of dea_opt.mesh.walk.Planes.track and the
 * scan of dea_opt.mesh.walk.window_faces,
 * compiled (optional: the numpy twins in walk.py give the same numbers, used where this module was
 * not built).
 *
 * Written by hand, as the walk itself (see walk.py): a ray steps across a mesh's edges from a face
 * it met before until its point on a face's plane lies inside the face. In numpy every step is a
 * dozen passes over gathered arrays; here it is one pass, each ray's record read once a step.
 * The arithmetic is the numpy loop's, operation for operation (no fused multiply-add on the
 * targets that have none by default), so both give the same numbers.
 *
 * No numpy headers: the arrays come through the buffer protocol, checked for size by the caller
 * (walk.py) and here for length and item size; every face index read is checked against the
 * table, so a bad index ends a ray (not found) instead of reading outside it.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <math.h>
#include <stdint.h>

static int take(PyObject *obj, Py_buffer *view, int writable, Py_ssize_t itemsize, Py_ssize_t count, const char *name)
{
    if (PyObject_GetBuffer(obj, view, (writable ? PyBUF_WRITABLE : 0) | PyBUF_C_CONTIGUOUS | PyBUF_FORMAT) < 0)
        return -1;
    if (view->itemsize != itemsize || view->len != itemsize * count) {
        PyErr_Format(PyExc_ValueError, "%s: expected %zd items of %zd bytes, got %zd bytes of items of %zd", name,
                     count, itemsize, view->len, view->itemsize);
        PyBuffer_Release(view);
        return -1;
    }
    return 0;
}

/* Every buffer of objs (count of them), those from first_writable on writable: 0, or -1 with none held. */
static int take_all(PyObject **objs, Py_buffer *views, int count, int first_writable, const Py_ssize_t *sizes,
                    const Py_ssize_t *counts, const char **names)
{
    for (int got = 0; got < count; got++)
        if (take(objs[got], &views[got], got >= first_writable, sizes[got], counts[got], names[got]) < 0) {
            for (int j = 0; j < got; j++)
                PyBuffer_Release(&views[j]);
            return -1;
        }
    return 0;
}

static PyObject *follow(PyObject *self, PyObject *args)
{
    PyObject *objs[10];
    Py_ssize_t k, n_faces;
    int steps;
    double on_face;
    if (!PyArg_ParseTuple(args, "nnidOOOOOOOOOO", &k, &n_faces, &steps, &on_face, &objs[0], &objs[1], &objs[2],
                          &objs[3], &objs[4], &objs[5], &objs[6], &objs[7], &objs[8], &objs[9]))
        return NULL;
    if (k < 0 || n_faces < 0 || steps < 0) {
        PyErr_SetString(PyExc_ValueError, "follow: negative size");
        return NULL;
    }
    /* faces (K,) int64, origins and directions (3, K), records (F, 12), across (3F,) int64, then the
       outputs: face (K,) int64, t, found (uint8), margin, along (K,) */
    static const char *names[10] = {"faces", "origins", "directions", "records", "across",
                                    "face", "t", "found", "margin", "along"};
    const Py_ssize_t sizes[10] = {8, 8, 8, 8, 8, 8, 8, 1, 8, 8};
    const Py_ssize_t counts[10] = {k, 3 * k, 3 * k, 12 * n_faces, 3 * n_faces, k, k, k, k, k};
    Py_buffer views[10];
    if (take_all(objs, views, 10, 5, sizes, counts, names) < 0)
        return NULL;
    const int64_t *faces = views[0].buf, *across = views[4].buf;
    const double *o = views[1].buf, *d = views[2].buf, *rec = views[3].buf;
    int64_t *face_out = views[5].buf;
    double *t_out = views[6].buf, *margin_out = views[8].buf, *along_out = views[9].buf;
    uint8_t *found_out = views[7].buf;

    Py_BEGIN_ALLOW_THREADS
    for (Py_ssize_t i = 0; i < k; i++) {
        int64_t f = faces[i];
        const double ox = o[i], oy = o[k + i], oz = o[2 * k + i];
        const double dx = d[i], dy = d[k + i], dz = d[2 * k + i];
        double t = NAN, margin = 0.0, along = 0.0;
        uint8_t found = 0;
        for (int step = 0; step <= steps && f >= 0 && f < n_faces; step++) {
            const double *r = rec + 12 * f;
            const double facing = (r[0] * dx + r[1] * dy) + r[2] * dz;
            const double dist = (r[3] - ((r[0] * ox + r[1] * oy) + r[2] * oz)) / facing;
            if (!isfinite(dist)) /* along the plane: the walk ends there */
                break;
            const double px = ox + dist * dx, py = oy + dist * dy, pz = oz + dist * dz;
            const double b1 = ((r[4] * px + r[5] * py) + r[6] * pz) - r[7];
            const double b2 = ((r[8] * px + r[9] * py) + r[10] * pz) - r[11];
            const double b0 = (1.0 - b1) - b2;
            double low = NAN; /* NaN coordinates (a degenerate face) give NaN, as np.minimum */
            if (!isnan(b0) && !isnan(b1) && !isnan(b2)) {
                low = b0 < b1 ? b0 : b1;
                low = low < b2 ? low : b2;
            }
            if (low >= -on_face) {
                t = dist, margin = low, along = facing, found = 1;
                break;
            }
            if (step == steps)
                break;
            const int corner = (b0 == low) ? 0 : ((b1 == low) ? 1 : 2);
            const int64_t next = across[3 * f + corner];
            if (next < 0) /* the mesh's boundary */
                break;
            f = next;
        }
        face_out[i] = f;
        t_out[i] = t;
        found_out[i] = found;
        margin_out[i] = margin;
        along_out[i] = along;
    }
    Py_END_ALLOW_THREADS

    for (int j = 0; j < 10; j++)
        PyBuffer_Release(&views[j]);
    Py_RETURN_NONE;
}

static PyObject *window(PyObject *self, PyObject *args)
{
    PyObject *objs[7];
    Py_ssize_t n1, n2;
    double low, high;
    if (!PyArg_ParseTuple(args, "nnddOOOOOOO", &n1, &n2, &low, &high, &objs[0], &objs[1], &objs[2], &objs[3],
                          &objs[4], &objs[5], &objs[6]))
        return NULL;
    if (n1 < 0 || n2 < 0) {
        PyErr_SetString(PyExc_ValueError, "window: negative size");
        return NULL;
    }
    /* met (n1,) int64, tried (n1,) uint8, centroids and normals (n1, 3), records (n2, 12), pose (12,):
       R row by row then the shift; the output: out (n1,) int64 */
    static const char *names[7] = {"met", "tried", "centroids", "normals", "records", "pose", "out"};
    const Py_ssize_t sizes[7] = {8, 1, 8, 8, 8, 8, 8};
    const Py_ssize_t counts[7] = {n1, n1, 3 * n1, 3 * n1, 12 * n2, 12, n1};
    Py_buffer views[7];
    if (take_all(objs, views, 7, 6, sizes, counts, names) < 0)
        return NULL;
    const int64_t *met = views[0].buf;
    const uint8_t *tried = views[1].buf;
    const double *c = views[2].buf, *n = views[3].buf, *rec = views[4].buf, *pose = views[5].buf;
    int64_t *out = views[6].buf;
    Py_ssize_t count = 0;

    Py_BEGIN_ALLOW_THREADS
    for (Py_ssize_t f = 0; f < n1; f++) {
        const int64_t j = met[f];
        if (j < 0 || j >= n2 || tried[f])
            continue;
        const double *r = rec + 12 * j;
        /* the plane's normal at the pose, R m, and the ray's gap to the plane (m . x = offset at the pose) */
        const double mx = (pose[0] * r[0] + pose[1] * r[1]) + pose[2] * r[2];
        const double my = (pose[3] * r[0] + pose[4] * r[1]) + pose[5] * r[2];
        const double mz = (pose[6] * r[0] + pose[7] * r[1]) + pose[8] * r[2];
        const double *cf = c + 3 * f, *nf = n + 3 * f;
        const double along = (nf[0] * mx + nf[1] * my) + nf[2] * mz;
        const double ahead = r[3] - (((cf[0] - pose[9]) * mx + (cf[1] - pose[10]) * my) + (cf[2] - pose[11]) * mz);
        const double gap = ahead / along;
        if (along < 0 && gap >= low && gap <= high)
            out[count++] = f;
    }
    Py_END_ALLOW_THREADS

    for (int j = 0; j < 7; j++)
        PyBuffer_Release(&views[j]);
    return PyLong_FromSsize_t(count);
}

static PyObject *track(PyObject *self, PyObject *args)
{
    PyObject *objs[16];
    Py_ssize_t n, n2;
    double on_face, shift2, max_gap, facing_min;
    if (!PyArg_ParseTuple(args, "nnddddOOOOOOOOOOOOOOOO", &n, &n2, &on_face, &shift2, &max_gap, &facing_min, &objs[0],
                          &objs[1], &objs[2], &objs[3], &objs[4], &objs[5], &objs[6], &objs[7], &objs[8], &objs[9],
                          &objs[10], &objs[11], &objs[12], &objs[13], &objs[14], &objs[15]))
        return NULL;
    if (n < 0 || n2 < 0) {
        PyErr_SetString(PyExc_ValueError, "track: negative size");
        return NULL;
    }
    /* pT, nT (3, N) rows, s (N,), valid (N,) uint8, pose (12,), faces2 (N,) int64, measured (N, 3),
       records (F, 12), altitude (F,), across (3F,) int64, m (N, 3), then tested (N, 3) and clear (N,),
       read and written, and the outputs: ownT (3, N), status (N,) uint8, next (N,) int64 */
    static const char *names[16] = {"pT", "nT", "s", "valid", "pose", "faces2", "measured", "records",
                                    "altitude", "across", "m", "tested", "clear", "ownT", "status", "next"};
    const Py_ssize_t sizes[16] = {8, 8, 8, 1, 8, 8, 8, 8, 8, 8, 8, 8, 8, 8, 1, 8};
    const Py_ssize_t counts[16] = {3 * n, 3 * n, n, n, 12, n, 3 * n, 12 * n2, n2, 3 * n2, 3 * n, 3 * n, n, 3 * n, n, n};
    Py_buffer views[16];
    if (take_all(objs, views, 16, 11, sizes, counts, names) < 0)
        return NULL;
    const double *pT = views[0].buf, *nT = views[1].buf, *s = views[2].buf, *pose = views[4].buf;
    const uint8_t *valid = views[3].buf;
    const int64_t *faces2 = views[5].buf, *across = views[9].buf;
    const double *measured = views[6].buf, *rec = views[7].buf, *altitude = views[8].buf, *m = views[10].buf;
    double *tested = views[11].buf, *clear = views[12].buf, *ownT = views[13].buf;
    uint8_t *status = views[14].buf;
    int64_t *next = views[15].buf;

    Py_BEGIN_ALLOW_THREADS
    for (Py_ssize_t i = 0; i < n; i++) {
        const int v = valid[i] != 0;
        const double a = v ? s[i] : 0.0;
        const double dx = pT[i] - pose[9], dy = pT[n + i] - pose[10], dz = pT[2 * n + i] - pose[11];
        const double nx = nT[i], ny = nT[n + i], nz = nT[2 * n + i];
        double o[3], d[3];
        for (int k = 0; k < 3; k++) { /* the ray's direction R^T n, and the hit R^T (p - shift) + a R^T n */
            d[k] = (pose[k] * nx + pose[3 + k] * ny) + pose[6 + k] * nz;
            o[k] = ((pose[k] * dx + pose[3 + k] * dy) + pose[6 + k] * dz) + a * d[k];
        }
        ownT[i] = o[0], ownT[n + i] = o[1], ownT[2 * n + i] = o[2];
        double *tst = tested + 3 * i;
        const double sx = o[0] - tst[0], sy = o[1] - tst[1], sz = o[2] - tst[2];
        int left = 0;
        int64_t across_to = -1;
        double low = NAN;
        if (!v || ((sx * sx + sy * sy) + sz * sz) >= clear[i] * clear[i]) {
            const int64_t f = faces2[i];
            if (f >= 0 && f < n2) {
                const double *r = rec + 12 * f;
                const double b1 = ((r[4] * o[0] + r[5] * o[1]) + r[6] * o[2]) - r[7];
                const double b2 = ((r[8] * o[0] + r[9] * o[1]) + r[10] * o[2]) - r[11];
                const double b0 = (1.0 - b1) - b2;
                if (!isnan(b0) && !isnan(b1) && !isnan(b2)) {
                    low = b0 < b1 ? b0 : b1;
                    low = low < b2 ? low : b2;
                }
                if (low >= -on_face && v) {
                    tst[0] = o[0], tst[1] = o[1], tst[2] = o[2];
                    clear[i] = (low > 0.0 ? low : 0.0) * altitude[f];
                } else {
                    left = 1;
                    /* the face across the edge opposite the first lowest coordinate (NaN read as 0) */
                    const double c0 = isnan(b0) ? 0.0 : b0, c1 = isnan(b1) ? 0.0 : b1, c2 = isnan(b2) ? 0.0 : b2;
                    const int corner = (c0 <= c1 && c0 <= c2) ? 0 : (c1 <= c2 ? 1 : 2);
                    across_to = across[3 * f + corner];
                    if (across_to < 0)
                        across_to = f;
                }
            } else
                left = 1;
        }
        /* a hit on its face whose ray turned past max_angle from facing it: met again there (lost) */
        const double *mi = m + 3 * i;
        const int turned = !left && -((d[0] * mi[0] + d[1] * mi[1]) + d[2] * mi[2]) < facing_min;
        if (turned)
            left = 1, across_to = faces2[i];
        const double *msr = measured + 3 * i;
        const double mx = o[0] - msr[0], my = o[1] - msr[1], mz = o[2] - msr[2];
        const int moved = !left && ((mx * mx + my * my) + mz * mz) > shift2;
        const int beyond = !left && s[i] > max_gap;
        status[i] = (uint8_t)(left | (moved << 1) | (beyond << 2) | (turned << 3));
        next[i] = across_to;
    }
    Py_END_ALLOW_THREADS

    for (int j = 0; j < 16; j++)
        PyBuffer_Release(&views[j]);
    Py_RETURN_NONE;
}

static PyMethodDef methods[] = {
    {"follow", follow, METH_VARARGS,
     "follow(k, n_faces, steps, on_face, faces, origins, directions, records, across, face, t, found, margin, along): "
     "Walker.follow's loop, writing the outputs in place."},
    {"track", track, METH_VARARGS,
     "track(n, n2, on_face, shift2, max_gap, facing_min, pT, nT, s, valid, pose, faces2, measured, records, "
     "altitude, across, m, tested, clear, ownT, status, next): Planes.track's pass, writing tested, clear and the outputs in place."},
    {"window", window, METH_VARARGS,
     "window(n1, n2, low, high, met, tried, centroids, normals, records, pose, out): window_faces's scan, "
     "writing the faces found to out; their number."},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module = {PyModuleDef_HEAD_INIT, "_walk", "Walker.follow's loop, Planes.track's pass and window_faces's scan, compiled.", -1, methods};

PyMODINIT_FUNC PyInit__walk(void) { return PyModule_Create(&module); }
