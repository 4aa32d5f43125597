/* Two passes over the springs of a finite-kinematics system, compiled (optional: the numpy passes
 * in finite_geometry.py and finite_system.py give the same numbers to rounding, and run where this
 * module was not built). Written math: formulations/finite.md ("Gap and its derivative", "Tangent").
 *
 * Written by hand: a Newton solve on the knee evaluates the gaps of ~1.3e4 springs a dozen times
 * and the tangent half a dozen; in numpy each is several passes over the springs with a temporary
 * array each (memory the solve's other passes then miss in cache), here one pass. Each spring's
 * products and sums are those of the numpy passes; numpy's matrix products (BLAS) group the sums
 * differently (in blocks, fused multiply-adds where the processor has them): the same numbers to
 * rounding, not bit for bit.
 *
 * No numpy headers: the arrays come through the buffer protocol, checked here for item type, shape
 * and strides, so that a wrong array is a ValueError, never a read outside it.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <math.h>
#include <string.h>

/* An array of float64: a vector of `count` items (rows == 0), or `rows` rows of `count` items each,
 * each row contiguous, the rows `*stride` items apart (the springs' rows live in longer buffers
 * kept between solves: a view of their first `count` columns); `-rows` rows: a small matrix,
 * C-contiguous (the rows `count` items apart). */
static int take(PyObject *obj, Py_buffer *view, int writable, int rows, Py_ssize_t count, Py_ssize_t *stride,
                const char *name)
{
    if (PyObject_GetBuffer(obj, view, (writable ? PyBUF_WRITABLE : 0) | PyBUF_RECORDS_RO) < 0)
        return -1;
    const int whole = rows < 0;
    rows = whole ? -rows : rows;
    const int ndim = rows ? 2 : 1;
    int ok = view->itemsize == 8 && view->format && strcmp(view->format, "d") == 0 && view->ndim == ndim;
    if (ok && rows)
        ok = view->shape[0] == rows && view->shape[1] == count && (view->strides[1] == 8 || count <= 1) &&
             view->strides[0] % 8 == 0 && (whole ? view->strides[0] == 8 * count : view->strides[0] >= 8 * count);
    else if (ok)
        ok = view->shape[0] == count && (view->strides[0] == 8 || count <= 1);
    if (!ok) {
        if (rows)
            PyErr_Format(PyExc_ValueError, "%s: expected float64 of shape (%d, %zd), %s, got %d dimensions of "
                         "items of %zd bytes, format '%s'", name, rows, count,
                         whole ? "C-contiguous" : "each row contiguous", view->ndim, view->itemsize,
                         view->format ? view->format : "?");
        else
            PyErr_Format(PyExc_ValueError, "%s: expected contiguous float64 of shape (%zd,), got %d dimensions of "
                         "items of %zd bytes, format '%s'", name, count, view->ndim, view->itemsize,
                         view->format ? view->format : "?");
        PyBuffer_Release(view);
        return -1;
    }
    *stride = rows ? view->strides[0] / 8 : 0;
    return 0;
}

/* Takes n arrays (rows[j] as in take, strides written to stride[j]), or none (an error set). */
static int take_all(PyObject **objs, Py_buffer *views, int n, int first_output, const int *rows,
                    const Py_ssize_t *counts, Py_ssize_t *stride, const char *const *names)
{
    for (int j = 0; j < n; j++)
        if (take(objs[j], &views[j], j >= first_output, rows[j], counts[j], &stride[j], names[j]) < 0) {
            for (int i = 0; i < j; i++)
                PyBuffer_Release(&views[i]);
            return -1;
        }
    return 0;
}

static void release_all(Py_buffer *views, int n)
{
    for (int j = 0; j < n; j++)
        PyBuffer_Release(&views[j]);
}

/* plane_gaps(k, facing, missed, transform, pT, nT, mT, qm, out_mT, out_along, out_s):
 * transform (4, 4) C-contiguous; pT, nT, mT (3, K) rows; qm (K,); outputs m' = R m (3, K),
 * along = n . m' (K,), s = (q . m + t . m' - p . m') / along where along < -facing, else missed. */
static PyObject *plane_gaps(PyObject *self, PyObject *args)
{
    Py_ssize_t k;
    double facing, missed;
    PyObject *objs[8];
    if (!PyArg_ParseTuple(args, "nddOOOOOOOO", &k, &facing, &missed, &objs[0], &objs[1], &objs[2], &objs[3],
                          &objs[4], &objs[5], &objs[6], &objs[7]))
        return NULL;
    if (k < 0) {
        PyErr_SetString(PyExc_ValueError, "plane_gaps: negative size");
        return NULL;
    }
    static const char *const names[8] = {"transform", "pT", "nT", "mT", "qm", "out_mT", "out_along", "out_s"};
    const int rows[8] = {-4, 3, 3, 3, 0, 3, 0, 0};
    const Py_ssize_t counts[8] = {4, k, k, k, k, k, k, k};
    Py_ssize_t st[8];
    Py_buffer views[8];
    if (take_all(objs, views, 8, 5, rows, counts, st, names) < 0)
        return NULL;
    const double *T = views[0].buf, *p = views[1].buf, *n = views[2].buf, *m = views[3].buf, *qm = views[4].buf;
    double *mo = views[5].buf, *along_out = views[6].buf, *s_out = views[7].buf;
    const Py_ssize_t sp = st[1], sn = st[2], sm = st[3], so = st[5];
    const double r00 = T[0], r01 = T[1], r02 = T[2], t0 = T[3];
    const double r10 = T[4], r11 = T[5], r12 = T[6], t1 = T[7];
    const double r20 = T[8], r21 = T[9], r22 = T[10], t2 = T[11];

    Py_BEGIN_ALLOW_THREADS
    for (Py_ssize_t i = 0; i < k; i++) {
        const double mx = m[i], my = m[sm + i], mz = m[2 * sm + i];
        const double a = (r00 * mx + r01 * my) + r02 * mz;
        const double b = (r10 * mx + r11 * my) + r12 * mz;
        const double c = (r20 * mx + r21 * my) + r22 * mz;
        const double along = (n[i] * a + n[sn + i] * b) + n[2 * sn + i] * c;
        double ahead = qm[i] + ((t0 * a + t1 * b) + t2 * c);
        ahead -= (p[i] * a + p[sp + i] * b) + p[2 * sp + i] * c;
        mo[i] = a, mo[so + i] = b, mo[2 * so + i] = c;
        along_out[i] = along;
        s_out[i] = along < -facing ? ahead / along : missed;
    }
    Py_END_ALLOW_THREADS

    release_all(views, 8);
    Py_RETURN_NONE;
}

/* tangent_sum(k, w, s, pT, nT, mT, arms, out): out (6, 6) = sum_i w_i a_i v_i^T over the springs
 * with w_i != 0, a_i = arms[:, i] (6, K), v_i = [m_i; h_i x m_i], h_i = p_i + s_i n_i. */
static PyObject *tangent_sum(PyObject *self, PyObject *args)
{
    Py_ssize_t k;
    PyObject *objs[7];
    if (!PyArg_ParseTuple(args, "nOOOOOOO", &k, &objs[0], &objs[1], &objs[2], &objs[3], &objs[4], &objs[5],
                          &objs[6]))
        return NULL;
    if (k < 0) {
        PyErr_SetString(PyExc_ValueError, "tangent_sum: negative size");
        return NULL;
    }
    static const char *const names[7] = {"w", "s", "pT", "nT", "mT", "arms", "out"};
    const int rows[7] = {0, 0, 3, 3, 3, 6, -6};
    const Py_ssize_t counts[7] = {k, k, k, k, k, k, 6};
    Py_ssize_t st[7];
    Py_buffer views[7];
    if (take_all(objs, views, 7, 6, rows, counts, st, names) < 0)
        return NULL;
    const Py_ssize_t sp = st[2], sn = st[3], sm = st[4], sa = st[5];
    const double *w = views[0].buf, *s = views[1].buf, *p = views[2].buf, *n = views[3].buf, *m = views[4].buf;
    const double *arms = views[5].buf;
    double *out = views[6].buf;
    double G[36] = {0.0};

    Py_BEGIN_ALLOW_THREADS
    for (Py_ssize_t i = 0; i < k; i++) {
        const double wi = w[i];
        if (wi == 0.0) /* an open spring: no stiffness (NaN weights are summed, and show) */
            continue;
        const double gap = s[i];
        const double mx = m[i], my = m[sm + i], mz = m[2 * sm + i];
        const double hx = p[i] + gap * n[i], hy = p[sp + i] + gap * n[sn + i], hz = p[2 * sp + i] + gap * n[2 * sn + i];
        const double v[6] = {mx, my, mz, hy * mz - hz * my, hz * mx - hx * mz, hx * my - hy * mx};
        for (int r = 0; r < 6; r++) {
            const double a = arms[r * sa + i] * wi;
            double *row = G + 6 * r;
            for (int c = 0; c < 6; c++)
                row[c] += a * v[c];
        }
    }
    Py_END_ALLOW_THREADS

    memcpy(out, G, sizeof G);
    release_all(views, 7);
    Py_RETURN_NONE;
}

static PyMethodDef methods[] = {
    {"plane_gaps", plane_gaps, METH_VARARGS,
     "plane_gaps(k, facing, missed, transform, pT, nT, mT, qm, out_mT, out_along, out_s): the springs' gaps "
     "to their target planes moved by transform, written in place."},
    {"tangent_sum", tangent_sum, METH_VARARGS,
     "tangent_sum(k, w, s, pT, nT, mT, arms, out): out (6, 6) = sum_i w_i arms_i [m_i; (p_i + s_i n_i) x m_i]^T "
     "over the springs with w_i != 0."},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module = {
    PyModuleDef_HEAD_INIT, "_finite", "A finite-kinematics system's passes over its springs, compiled.", -1, methods};

PyMODINIT_FUNC PyInit__finite(void) { return PyModule_Create(&module); }
