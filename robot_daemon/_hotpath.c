/* The motion tick's per-value work compiled: the gait's leg IK, the goals' conversion to servo
 * units and the joints and IMU messages' msgpack bytes. Optional (setup.py builds it with optional=True): each function here has a
 * pure-Python twin that stays the definition (robot_daemon/motion/walking/ik.py,
 * robot_daemon/bus/calibration.py, msgpack through schemas/packed.py), and
 * tests/unit/test_hotpath.py checks the two give the same bits on seeded random inputs.
 *
 * The same bits need the same IEEE operations in the same order as the Python code, each
 * rounded to a double as Python rounds it (every Python float operation stores its result as a
 * double): one operation per assignment below, and on i386, whose Python computes on the x87
 * unit, setup.py builds this with -fexcess-precision=standard so that every assignment rounds
 * to double there too. libm's sin, cos, acos and atan2 are the ones Python's math module calls;
 * math.atan2's own handling of zeros, infinities and NaNs is copied (py_atan2), as is float's
 * % (py_mod) and round() (py_round). Anything outside what is copied here (an input that is not
 * a float, a non-finite angle) goes to the Python function, which says what is wrong.
 *
 * CPython's API only: Debian's gcc and python3-dev build it, nothing else. */

#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <limits.h>
#include <math.h>

/* -- the leg IK (ik.leg_ik_end_point) --------------------------------------------------------- */

static double ANKLE, LEG, THIGH2, CALF2, TWO_THIGH_CALF, CALF, THIGH, PI, TAU;
static PyObject *ik_fallback; /* the pure-Python leg_ik_end_point */

/* Python's math.atan2 (Modules/mathmodule.c, m_atan2) */
static double py_atan2(double y, double x)
{
    if (isnan(x) || isnan(y))
        return NAN;
    if (isinf(y)) {
        if (isinf(x)) {
            if (copysign(1., x) == 1.)
                return copysign(0.25 * PI, y);
            else
                return copysign(0.75 * PI, y);
        }
        return copysign(0.5 * PI, y);
    }
    if (isinf(x) || y == 0.) {
        if (copysign(1., x) == 1.)
            return 0. * y;
        else
            return copysign(PI, y);
    }
    return atan2(y, x);
}

/* Python's float % (Objects/floatobject.c, float_rem), for a non-zero divisor */
static double py_mod(double v, double w)
{
    double mod = fmod(v, w);
    if (mod) {
        if ((w < 0) != (mod < 0))
            mod += w;
    }
    else {
        mod = copysign(0.0, w);
    }
    return mod;
}

static PyObject *hot_configure_leg(PyObject *self, PyObject *args)
{
    PyObject *fallback;
    if (!PyArg_ParseTuple(args, "dddddddddO", &ANKLE, &LEG, &THIGH2, &CALF2, &TWO_THIGH_CALF,
                          &CALF, &THIGH, &PI, &TAU, &fallback))
        return NULL;
    Py_XDECREF(ik_fallback);
    Py_INCREF(fallback);
    ik_fallback = fallback;
    Py_RETURN_NONE;
}

/* The IK of six floats into out: 0 reached, 1 out of reach (None), 2 the Python's to do */
static int ik_core(const double *in, double *out)
{
    double x = in[0], y = in[1], z = in[2], roll = in[3], pitch = in[4], yaw = in[5];
    if (!isfinite(roll) || !isfinite(pitch) || !isfinite(yaw))  /* math.cos raises */
        return 2;
    double cr = cos(roll), sr = sin(roll);
    double cp = cos(pitch), sp = sin(pitch);
    double cy = cos(yaw), sy = sin(yaw);
    double t, u;
    double r00 = cy * cp;
    t = cy * sp; t = t * sr; u = sy * cr;
    double r01 = t - u;
    t = cy * sp; t = t * cr; u = sy * sr;
    double r02 = t + u;
    double r10 = sy * cp;
    t = sy * sp; t = t * sr; u = cy * cr;
    double r11 = t + u;
    t = sy * sp; t = t * cr; u = cy * sr;
    double r12 = t - u;
    double r21 = cp * sr, r22 = cp * cr;
    t = r02 * ANKLE;
    double ax = x + t;
    t = r12 * ANKLE;
    double ay = y + t;
    t = z - LEG; u = r22 * ANKLE;
    double az = t + u;
    t = ax * ax; u = ay * ay; t = t + u; u = az * az;
    double dist2 = t + u;
    t = dist2 - THIGH2; t = t - CALF2;
    double cos_knee = t / TWO_THIGH_CALF;
    if (!(-1.0 <= cos_knee && cos_knee <= 1.0) || dist2 < 1e-12)
        return 1;
    double knee = acos(cos_knee);
    t = r01 * ax; u = r11 * ay; t = t + u; u = r21 * az; t = t + u;
    double v1 = -t;
    t = r02 * ax; u = r12 * ay; t = t + u; u = r22 * az; t = t + u;
    double v2 = -t;
    double ankle_roll = v2 >= 0 ? py_atan2(v1, v2) : py_atan2(-v1, -v2);
    double ca = cos(ankle_roll), sa = sin(ankle_roll);
    t = r01 * ca; u = r02 * sa;
    double s01 = t - u;
    t = r11 * ca; u = r12 * sa;
    double s11 = t - u;
    t = r21 * ca; u = r22 * sa;
    double s21 = t - u;
    t = r01 * sa; u = r02 * ca;
    double s02 = t + u;
    t = r11 * sa; u = r12 * ca;
    double s12 = t + u;
    double hip_yaw = py_atan2(-s01, s11);
    double cw = cos(hip_yaw), sw = sin(hip_yaw);
    t = cw * s11; u = sw * s01; t = t - u;
    double hip_roll = py_atan2(s21, t);
    double n, d;
    t = cw * s02; u = sw * s12; n = t + u;
    t = cw * r00; u = sw * r10; d = t + u;
    double pitch_sum = py_atan2(n, d);
    t = cw * ay; u = sw * ax;
    double p1 = t - u;
    t = cw * ax; u = sw * ay;
    double q0 = t + u;
    t = cos(hip_roll); t = t * az; u = sin(hip_roll); u = u * p1;
    double q2 = t - u;
    t = sin(knee);
    double ux = -CALF * t;
    t = cos(knee); t = CALF * t;
    double uz = -THIGH - t;
    t = py_atan2(q0, q2); u = py_atan2(ux, uz); t = t - u; t = t + PI; t = py_mod(t, TAU);
    double hip_pitch = t - PI;
    t = pitch_sum - hip_pitch; t = t - knee; t = t + PI; t = py_mod(t, TAU);
    double ankle_pitch = t - PI;
    out[0] = hip_yaw; out[1] = hip_roll; out[2] = hip_pitch;
    out[3] = knee; out[4] = ankle_pitch; out[5] = ankle_roll;
    return 0;
}

static PyObject *hot_leg_ik_end_point(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    double in[6], out[6];
    if (ik_fallback == NULL) {
        PyErr_SetString(PyExc_RuntimeError, "_hotpath.leg_ik_end_point: configure_leg first");
        return NULL;
    }
    if (nargs != 6)
        return PyObject_Vectorcall(ik_fallback, args, nargs, NULL);
    for (int i = 0; i < 6; i++) {
        if (!PyFloat_CheckExact(args[i]))
            return PyObject_Vectorcall(ik_fallback, args, nargs, NULL);
        in[i] = PyFloat_AS_DOUBLE(args[i]);
    }
    int r = ik_core(in, out);
    if (r == 2)
        return PyObject_Vectorcall(ik_fallback, args, nargs, NULL);
    if (r == 1)
        Py_RETURN_NONE;
    return Py_BuildValue("(dddddd)", out[0], out[1], out[2], out[3], out[4], out[5]);
}

/* leg_servo_angles(end_point, ids, directions, pitch_at, pitch_shift): ik.leg_servo_angles
 * after its side is looked up: {ids[i]: directions[i] * angle[i]}, the hip pitch's
 * (ids[pitch_at]) less pitch_shift; None out of reach; NotImplemented for the Python's to do
 * (an end point not of six floats, a non-finite angle, a direction not an int). */
static PyObject *hot_leg_servo_angles(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    double in[6], out[6];
    if (nargs != 5 || !PyTuple_CheckExact(args[1]) || !PyTuple_CheckExact(args[2])
        || PyTuple_GET_SIZE(args[1]) != 6 || PyTuple_GET_SIZE(args[2]) != 6
        || !PyLong_CheckExact(args[3]) || !PyFloat_CheckExact(args[4])
        || !(PyTuple_CheckExact(args[0]) || PyList_CheckExact(args[0]))
        || PySequence_Fast_GET_SIZE(args[0]) != 6)
        Py_RETURN_NOTIMPLEMENTED;
    PyObject **point = PySequence_Fast_ITEMS(args[0]);
    for (int i = 0; i < 6; i++) {
        if (!PyFloat_CheckExact(point[i]))
            Py_RETURN_NOTIMPLEMENTED;
        in[i] = PyFloat_AS_DOUBLE(point[i]);
    }
    long pitch_at = PyLong_AsLong(args[3]);
    if (pitch_at < 0 || pitch_at > 5) {
        PyErr_Clear();
        Py_RETURN_NOTIMPLEMENTED;
    }
    double dirs[6];
    for (int i = 0; i < 6; i++) {
        PyObject *d = PyTuple_GET_ITEM(args[2], i);
        if (!PyLong_CheckExact(d) || !PyLong_CheckExact(PyTuple_GET_ITEM(args[1], i)))
            Py_RETURN_NOTIMPLEMENTED;
        long v = PyLong_AsLong(d);
        if (v < -1 || v > 1) {  /* a direction is -1, 0 or 1: exact as a double */
            PyErr_Clear();
            Py_RETURN_NOTIMPLEMENTED;
        }
        dirs[i] = (double)v;
    }
    int r = ik_core(in, out);
    if (r == 2)
        Py_RETURN_NOTIMPLEMENTED;
    if (r == 1)
        Py_RETURN_NONE;
    PyObject *servo = PyDict_New();
    if (servo == NULL)
        return NULL;
    for (int i = 0; i < 6; i++) {
        double v = dirs[i] * out[i];
        if (i == pitch_at)
            v = v - PyFloat_AS_DOUBLE(args[4]);
        PyObject *f = PyFloat_FromDouble(v);
        if (f == NULL || PyDict_SetItem(servo, PyTuple_GET_ITEM(args[1], i), f) < 0) {
            Py_XDECREF(f);
            Py_DECREF(servo);
            return NULL;
        }
        Py_DECREF(f);
    }
    return servo;
}

/* -- the goals in servo units (Calibration.goals_raw) ----------------------------------------- */

/* Python's round() of a float, to a whole double (Objects/floatobject.c, float___round__) */
static double py_round(double x)
{
    double rounded = round(x);
    double diff = x - rounded;
    if (fabs(diff) == 0.5) {
        double half = x / 2.0;
        rounded = 2.0 * round(half);
    }
    return rounded;
}

/* goals_raw(sign, offset, lo, hi, rads, k, c): [round((s * r + o) / k) + c for each goal] when
 * every goal r is within lo..hi; None when one is not (or is NaN); NotImplemented when any value
 * is not a float or the lists differ in length, for the caller's Python to handle. */
static PyObject *hot_goals_raw(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    if (nargs != 7) {
        PyErr_SetString(PyExc_TypeError, "goals_raw takes 7 arguments");
        return NULL;
    }
    for (int i = 0; i < 5; i++)
        if (!PyList_CheckExact(args[i]))
            Py_RETURN_NOTIMPLEMENTED;
    if (!PyFloat_CheckExact(args[5]) || !PyLong_CheckExact(args[6]))
        Py_RETURN_NOTIMPLEMENTED;
    Py_ssize_t n = PyList_GET_SIZE(args[4]);
    for (int i = 0; i < 4; i++)
        if (PyList_GET_SIZE(args[i]) != n)
            Py_RETURN_NOTIMPLEMENTED;
    double k = PyFloat_AS_DOUBLE(args[5]);
    long c = PyLong_AsLong(args[6]);
    if (c == -1 && PyErr_Occurred())
        return NULL;
    for (Py_ssize_t j = 0; j < n; j++)
        for (int i = 0; i < 5; i++)
            if (!PyFloat_CheckExact(PyList_GET_ITEM(args[i], j)))
                Py_RETURN_NOTIMPLEMENTED;
    PyObject *out = PyList_New(n);
    if (out == NULL)
        return NULL;
    for (Py_ssize_t j = 0; j < n; j++) {
        double s = PyFloat_AS_DOUBLE(PyList_GET_ITEM(args[0], j));
        double o = PyFloat_AS_DOUBLE(PyList_GET_ITEM(args[1], j));
        double lo = PyFloat_AS_DOUBLE(PyList_GET_ITEM(args[2], j));
        double hi = PyFloat_AS_DOUBLE(PyList_GET_ITEM(args[3], j));
        double r = PyFloat_AS_DOUBLE(PyList_GET_ITEM(args[4], j));
        if (!(lo <= r && r <= hi)) {
            Py_DECREF(out);
            Py_RETURN_NONE;
        }
        double t = s * r;
        t = t + o;
        t = t / k;
        t = py_round(t);
        if (!(fabs(t) < 1e15)) {  /* beyond a long on i386: Python's ints take it */
            Py_DECREF(out);
            Py_RETURN_NOTIMPLEMENTED;
        }
        PyObject *v = PyLong_FromLongLong((long long)t + c);
        if (v == NULL) {
            Py_DECREF(out);
            return NULL;
        }
        PyList_SET_ITEM(out, j, v);
    }
    return out;
}

/* -- msgpack of the joints and IMU messages (schemas/packed.py's Prepacked) ------------------ */

/* The bytes msgpack-python's Packer(use_bin_type=True) gives for None, bool, int, float, str,
 * bytes and lists, tuples or dicts of them; anything else (a subclass included) is left to
 * msgpack. */

typedef struct {
    char *buf;
    Py_ssize_t len, cap;
} Out;

static int out_reserve(Out *o, Py_ssize_t n)
{
    if (o->len + n <= o->cap)
        return 0;
    Py_ssize_t cap = o->cap * 2 > o->len + n ? o->cap * 2 : o->len + n + 256;
    char *buf = PyMem_Realloc(o->buf, cap);
    if (buf == NULL) {
        PyErr_NoMemory();
        return -1;
    }
    o->buf = buf;
    o->cap = cap;
    return 0;
}

static int out_write(Out *o, const char *data, Py_ssize_t n)
{
    if (out_reserve(o, n) < 0)
        return -1;
    memcpy(o->buf + o->len, data, n);
    o->len += n;
    return 0;
}

static int out_be(Out *o, unsigned char head, unsigned long long v, int n)
{
    if (out_reserve(o, 1 + n) < 0)
        return -1;
    unsigned char *b = (unsigned char *)o->buf + o->len;
    b[0] = head;
    for (int i = n; i >= 1; i--, v >>= 8)
        b[i] = (unsigned char)(v & 0xFF);
    o->len += 1 + n;
    return 0;
}

/* msgpack's pack_template.h: the smallest form, signed ones only below -32 */
static int pack_int(Out *o, long long d)
{
    if (d < -(1LL << 5)) {
        if (d < -(1LL << 15))
            return d < -(1LL << 31) ? out_be(o, 0xd3, (unsigned long long)d, 8)
                                    : out_be(o, 0xd2, (unsigned long long)d & 0xFFFFFFFFULL, 4);
        return d < -(1LL << 7) ? out_be(o, 0xd1, (unsigned long long)d & 0xFFFF, 2)
                               : out_be(o, 0xd0, (unsigned long long)d & 0xFF, 1);
    }
    if (d < (1LL << 7)) {
        char c = (char)(d & 0xFF);
        return out_write(o, &c, 1);
    }
    if (d < (1LL << 16))
        return d < (1LL << 8) ? out_be(o, 0xcc, (unsigned long long)d, 1)
                              : out_be(o, 0xcd, (unsigned long long)d, 2);
    return d < (1LL << 32) ? out_be(o, 0xce, (unsigned long long)d, 4)
                           : out_be(o, 0xcf, (unsigned long long)d, 8);
}

/* 0 packed, 1 not a type packed here (the caller hands back NotImplemented), -1 error */
/* An array's or a map's header in its smallest form: fix (0x90 or 0x80, with n < 16), else
 * head16 and its 32-bit form head16 + 1. 0 packed, -1 out of memory, 1 too long for msgpack. */
static int pack_header(Out *o, Py_ssize_t n, unsigned char fix, unsigned char head16)
{
    int r;
    if (n < 16) {
        char h = (char)(fix | n);
        r = out_write(o, &h, 1);
    }
    else if (n < 65536)
        r = out_be(o, head16, (unsigned long long)n, 2);
    else if (n <= 0xFFFFFFFFLL)
        r = out_be(o, (unsigned char)(head16 + 1), (unsigned long long)n, 4);
    else
        return 1;
    return r < 0 ? -1 : 0;
}

static int pack_obj(Out *o, PyObject *v, int depth)
{
    if (v == Py_None)
        return out_write(o, "\xc0", 1);
    if (v == Py_True)
        return out_write(o, "\xc3", 1);
    if (v == Py_False)
        return out_write(o, "\xc2", 1);
    if (PyFloat_CheckExact(v)) {
        union { double d; unsigned long long u; } bits;
        bits.d = PyFloat_AS_DOUBLE(v);
        return out_be(o, 0xcb, bits.u, 8);
    }
    if (PyLong_CheckExact(v)) {
        int overflow;
        long long d = PyLong_AsLongLongAndOverflow(v, &overflow);
        if (overflow != 0 || (d == -1 && PyErr_Occurred())) {
            PyErr_Clear();
            return 1;  /* beyond 64 bits signed: msgpack's unsigned or its error */
        }
        return pack_int(o, d);
    }
    if (PyUnicode_CheckExact(v)) {
        Py_ssize_t n;
        const char *s = PyUnicode_AsUTF8AndSize(v, &n);
        if (s == NULL) {
            PyErr_Clear();
            return 1;  /* a lone surrogate: msgpack says what is wrong */
        }
        int r;
        if (n < 32) {
            char h = (char)(0xa0 | n);
            r = out_write(o, &h, 1);
        }
        else if (n < 256)
            r = out_be(o, 0xd9, (unsigned long long)n, 1);
        else if (n < 65536)
            r = out_be(o, 0xda, (unsigned long long)n, 2);
        else if (n <= 0xFFFFFFFFLL)
            r = out_be(o, 0xdb, (unsigned long long)n, 4);
        else
            return 1;
        return r < 0 ? -1 : out_write(o, s, n);
    }
    if (PyBytes_CheckExact(v)) {
        Py_ssize_t n = PyBytes_GET_SIZE(v);
        int r;
        if (n < 256)
            r = out_be(o, 0xc4, (unsigned long long)n, 1);
        else if (n < 65536)
            r = out_be(o, 0xc5, (unsigned long long)n, 2);
        else if (n <= 0xFFFFFFFFLL)
            r = out_be(o, 0xc6, (unsigned long long)n, 4);
        else
            return 1;
        return r < 0 ? -1 : out_write(o, PyBytes_AS_STRING(v), n);
    }
    if (PyList_CheckExact(v) || PyTuple_CheckExact(v)) {
        if (depth > 8)
            return 1;
        Py_ssize_t n = PySequence_Fast_GET_SIZE(v);
        PyObject **items = PySequence_Fast_ITEMS(v);
        int r = pack_header(o, n, 0x90, 0xdc);
        if (r != 0)
            return r;
        for (Py_ssize_t i = 0; i < n; i++) {
            r = pack_obj(o, items[i], depth + 1);
            if (r != 0)
                return r;
        }
        return 0;
    }
    if (PyDict_CheckExact(v)) {
        /* msgpack's map: the header's smallest form, then each key and its value in the
         * dict's order (msgpack walks it with PyDict_Next too). Packing runs no Python code,
         * so nothing changes the dict meanwhile. */
        if (depth > 8)
            return 1;
        Py_ssize_t n = PyDict_GET_SIZE(v);
        int r = pack_header(o, n, 0x80, 0xde);
        if (r != 0)
            return r;
        Py_ssize_t pos = 0;
        PyObject *key, *value;
        while (PyDict_Next(v, &pos, &key, &value)) {
            r = pack_obj(o, key, depth + 1);
            if (r == 0)
                r = pack_obj(o, value, depth + 1);
            if (r != 0)
                return r;
        }
        return 0;
    }
    return 1;
}

/* packb(obj): msgpack's bytes of obj (Packer(use_bin_type=True).pack) for what pack_obj packs
 * (None, bools, floats, ints of 64 bits, str, bytes, lists, tuples and dicts of those, nine
 * deep); NotImplemented for anything else, which msgpack packs. */
static PyObject *hot_packb(PyObject *self, PyObject *obj)
{
    Out o = {NULL, 0, 0};
    int r = out_reserve(&o, 4096);
    if (r == 0)
        r = pack_obj(&o, obj, 0);
    PyObject *result = NULL;
    if (r == 0)
        result = PyBytes_FromStringAndSize(o.buf, o.len);
    else if (r == 1) {
        result = Py_NotImplemented;
        Py_INCREF(result);
    }
    PyMem_Free(o.buf);
    return result;
}

/* pack_fields(head, keys, values, tail): head, then each key's packed bytes followed by its
 * value packed, then tail: the bytes of a message whose fixed parts are packed already
 * (Prepacked); NotImplemented when a value is of a type left to msgpack. */
static PyObject *hot_pack_fields(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    if (nargs != 4 || !PyBytes_CheckExact(args[0]) || !PyTuple_CheckExact(args[1])
        || !(PyList_CheckExact(args[2]) || PyTuple_CheckExact(args[2]))
        || !PyBytes_CheckExact(args[3])) {
        PyErr_SetString(PyExc_TypeError,
                        "pack_fields(head: bytes, keys: tuple, values: list, tail: bytes)");
        return NULL;
    }
    PyObject *keys = args[1], *values = args[2];
    Py_ssize_t n = PyTuple_GET_SIZE(keys);
    if (PySequence_Fast_GET_SIZE(values) != n)
        Py_RETURN_NOTIMPLEMENTED;
    PyObject **items = PySequence_Fast_ITEMS(values);
    Out o = {NULL, 0, 0};
    int r = out_reserve(&o, 2048);
    if (r == 0)
        r = out_write(&o, PyBytes_AS_STRING(args[0]), PyBytes_GET_SIZE(args[0]));
    for (Py_ssize_t i = 0; r == 0 && i < n; i++) {
        PyObject *key = PyTuple_GET_ITEM(keys, i);
        if (!PyBytes_CheckExact(key)) {
            PyMem_Free(o.buf);
            PyErr_SetString(PyExc_TypeError, "pack_fields: the keys are packed bytes");
            return NULL;
        }
        r = out_write(&o, PyBytes_AS_STRING(key), PyBytes_GET_SIZE(key));
        if (r == 0)
            r = pack_obj(&o, items[i], 0);
    }
    if (r == 0)
        r = out_write(&o, PyBytes_AS_STRING(args[3]), PyBytes_GET_SIZE(args[3]));
    PyObject *result = NULL;
    if (r == 0)
        result = PyBytes_FromStringAndSize(o.buf, o.len);
    else if (r == 1) {
        result = Py_NotImplemented;
        Py_INCREF(result);
    }
    PyMem_Free(o.buf);
    return result;
}

/* positions_list(raw, sign, offset, k, c): [s * ((r - c) * k - o) for each raw r] (joint
 * angles of raw servo positions, Calibration.positions_list); NotImplemented when a value is
 * not an int (raw) or a float (sign, offset) or the lists differ in length. */
static PyObject *hot_positions_list(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    if (nargs != 5) {
        PyErr_SetString(PyExc_TypeError, "positions_list takes 5 arguments");
        return NULL;
    }
    for (int i = 0; i < 3; i++)
        if (!PyList_CheckExact(args[i]))
            Py_RETURN_NOTIMPLEMENTED;
    if (!PyFloat_CheckExact(args[3]) || !PyLong_CheckExact(args[4]))
        Py_RETURN_NOTIMPLEMENTED;
    Py_ssize_t n = PyList_GET_SIZE(args[0]);
    if (PyList_GET_SIZE(args[1]) != n || PyList_GET_SIZE(args[2]) != n)
        Py_RETURN_NOTIMPLEMENTED;
    double k = PyFloat_AS_DOUBLE(args[3]);
    long c = PyLong_AsLong(args[4]);
    if (c == -1 && PyErr_Occurred())
        return NULL;
    PyObject *out = PyList_New(n);
    if (out == NULL)
        return NULL;
    for (Py_ssize_t j = 0; j < n; j++) {
        PyObject *r = PyList_GET_ITEM(args[0], j);
        PyObject *s = PyList_GET_ITEM(args[1], j), *o = PyList_GET_ITEM(args[2], j);
        if (!PyLong_CheckExact(r) || !PyFloat_CheckExact(s) || !PyFloat_CheckExact(o)) {
            Py_DECREF(out);
            Py_RETURN_NOTIMPLEMENTED;
        }
        long raw = PyLong_AsLong(r);
        if ((raw == -1 && PyErr_Occurred()) || raw > (1L << 30) || raw < -(1L << 30)) {
            PyErr_Clear();  /* beyond a servo's word: the Python's */
            Py_DECREF(out);
            Py_RETURN_NOTIMPLEMENTED;
        }
        double t = (double)(raw - c);  /* an int times a float: the int made a double */
        t = t * k;
        t = t - PyFloat_AS_DOUBLE(o);
        t = PyFloat_AS_DOUBLE(s) * t;
        PyObject *v = PyFloat_FromDouble(t);
        if (v == NULL) {
            Py_DECREF(out);
            return NULL;
        }
        PyList_SET_ITEM(out, j, v);
    }
    return out;
}

/* -- the bulk read's answer and the state it fills (bus/bulk_receive.py, bus/sensor_read.py) -- */

/* take_whole(buf, order, lengths, data, errors): bulk_receive._take_whole_py compiled. ``buf``
 * is every reply of a bulk read in order, whole (FF FF ID LEN ERR data CHK each, ``lengths``
 * data bytes of ``order``'s devices). True and each reply's data into ``data`` (error bits into
 * ``errors`` where not 0) when every header and checksum is a good reply's; False, nothing taken,
 * when one is not (the reply-by-reply loop then finds which); NotImplemented when the
 * arguments are not what the Python takes (the Python's then). */
static PyObject *hot_take_whole(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    if (nargs != 5) {
        PyErr_SetString(PyExc_TypeError, "take_whole takes 5 arguments");
        return NULL;
    }
    PyObject *buf = args[0], *order = args[1], *lengths = args[2];
    PyObject *data = args[3], *errors = args[4];
    if (!PyBytes_CheckExact(buf) || !PyTuple_CheckExact(order) || !PyTuple_CheckExact(lengths)
        || !PyDict_CheckExact(data) || !PyDict_CheckExact(errors))
        Py_RETURN_NOTIMPLEMENTED;
    Py_ssize_t n = PyTuple_GET_SIZE(order);
    if (PyTuple_GET_SIZE(lengths) != n || n > 256)
        Py_RETURN_NOTIMPLEMENTED;
    const unsigned char *b = (const unsigned char *)PyBytes_AS_STRING(buf);
    Py_ssize_t have = PyBytes_GET_SIZE(buf), pos = 0;
    long ids[256], lens[256];
    for (Py_ssize_t k = 0; k < n; k++) {
        PyObject *i = PyTuple_GET_ITEM(order, k), *l = PyTuple_GET_ITEM(lengths, k);
        if (!PyLong_CheckExact(i) || !PyLong_CheckExact(l))
            Py_RETURN_NOTIMPLEMENTED;
        ids[k] = PyLong_AsLong(i);
        lens[k] = PyLong_AsLong(l);
        if (ids[k] < 0 || ids[k] > 255 || lens[k] < 0 || lens[k] > 253) {
            PyErr_Clear();
            Py_RETURN_NOTIMPLEMENTED;
        }
        pos += lens[k] + 6;
    }
    if (pos != have)  /* the struct's size: the Python's to refuse */
        Py_RETURN_NOTIMPLEMENTED;
    /* every header first (as the Python compares them all before any checksum), then every
     * checksum: ID + LEN + ERR + data + CHK of a good reply sum to 0xFF (mod 256) */
    pos = 0;
    for (Py_ssize_t k = 0; k < n; k++) {
        if (b[pos] != 0xFF || b[pos + 1] != 0xFF || b[pos + 2] != ids[k]
            || b[pos + 3] != lens[k] + 2)
            Py_RETURN_FALSE;
        pos += lens[k] + 6;
    }
    pos = 0;
    for (Py_ssize_t k = 0; k < n; k++) {
        unsigned int sum = 0;
        Py_ssize_t end = pos + lens[k] + 6;
        for (Py_ssize_t q = pos + 2; q < end; q++)
            sum += b[q];
        if ((sum & 0xFF) != 0xFF)
            Py_RETURN_FALSE;
        pos = end;
    }
    pos = 0;
    for (Py_ssize_t k = 0; k < n; k++) {
        PyObject *d = PyBytes_FromStringAndSize((const char *)b + pos + 5, lens[k]);
        if (d == NULL || PyDict_SetItem(data, PyTuple_GET_ITEM(order, k), d) < 0) {
            Py_XDECREF(d);
            return NULL;
        }
        Py_DECREF(d);
        pos += lens[k] + 6;
    }
    pos = 0;
    for (Py_ssize_t k = 0; k < n; k++) {
        if (b[pos + 4]) {
            PyObject *e = PyLong_FromLong(b[pos + 4]);
            if (e == NULL || PyDict_SetItem(errors, PyTuple_GET_ITEM(order, k), e) < 0) {
                Py_XDECREF(e);
                return NULL;
            }
            Py_DECREF(e);
        }
        pos += lens[k] + 6;
    }
    Py_RETURN_TRUE;
}

/* take_run(buf, pos, due, order, lengths, data, errors): bulk_receive._take_run_py compiled:
 * the replies from the ``due``-th of ``order`` on, at ``pos`` in ``buf``, each whole and in
 * order, into ``data`` and ``errors``, up to the first not all in ``buf``: (due, pos, True)
 * where the next one starts, or (due, pos, False) at the first that is not a good reply
 * (header or checksum). NotImplemented when the arguments are not what that takes. */
static PyObject *hot_take_run(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    if (nargs != 7) {
        PyErr_SetString(PyExc_TypeError, "take_run takes 7 arguments");
        return NULL;
    }
    PyObject *buf = args[0], *order = args[3], *lengths = args[4];
    PyObject *data = args[5], *errors = args[6];
    if (!PyBytes_CheckExact(buf) || !PyLong_CheckExact(args[1]) || !PyLong_CheckExact(args[2])
        || !PyTuple_CheckExact(order) || !PyTuple_CheckExact(lengths)
        || !PyDict_CheckExact(data) || !PyDict_CheckExact(errors))
        Py_RETURN_NOTIMPLEMENTED;
    Py_ssize_t n = PyTuple_GET_SIZE(order);
    Py_ssize_t have = PyBytes_GET_SIZE(buf);
    Py_ssize_t pos = PyLong_AsSsize_t(args[1]), due = PyLong_AsSsize_t(args[2]);
    if ((pos == -1 || due == -1) && PyErr_Occurred()) {
        PyErr_Clear();
        Py_RETURN_NOTIMPLEMENTED;
    }
    if (PyTuple_GET_SIZE(lengths) != n || pos < 0 || pos > PY_SSIZE_T_MAX / 2 || due < 0
        || due > n)
        Py_RETURN_NOTIMPLEMENTED;
    for (Py_ssize_t k = due; k < n; k++) {  /* everything checked before anything is taken */
        PyObject *i = PyTuple_GET_ITEM(order, k), *l = PyTuple_GET_ITEM(lengths, k);
        if (!PyLong_CheckExact(i) || !PyLong_CheckExact(l))
            Py_RETURN_NOTIMPLEMENTED;
        long id = PyLong_AsLong(i), len = PyLong_AsLong(l);
        if (id < 0 || id > 255 || len < 0 || len > 253) {
            PyErr_Clear();
            Py_RETURN_NOTIMPLEMENTED;
        }
    }
    const unsigned char *b = (const unsigned char *)PyBytes_AS_STRING(buf);
    int good = 1;
    while (due < n) {
        long id = PyLong_AsLong(PyTuple_GET_ITEM(order, due));
        long len = PyLong_AsLong(PyTuple_GET_ITEM(lengths, due));
        Py_ssize_t end = pos + len + 6;
        if (have < end)
            break;
        unsigned int sum = 0;
        for (Py_ssize_t q = pos + 2; q < end; q++)
            sum += b[q];
        if (b[pos] != 0xFF || b[pos + 1] != 0xFF || b[pos + 2] != id || b[pos + 3] != len + 2
            || (sum & 0xFF) != 0xFF) {
            good = 0;
            break;
        }
        PyObject *key = PyTuple_GET_ITEM(order, due);
        PyObject *d = PyBytes_FromStringAndSize((const char *)b + pos + 5, len);
        if (d == NULL || PyDict_SetItem(data, key, d) < 0) {
            Py_XDECREF(d);
            return NULL;
        }
        Py_DECREF(d);
        if (b[pos + 4]) {
            PyObject *e = PyLong_FromLong(b[pos + 4]);
            if (e == NULL || PyDict_SetItem(errors, key, e) < 0) {
                Py_XDECREF(e);
                return NULL;
            }
            Py_DECREF(e);
        }
        due++;
        pos = end;
    }
    return Py_BuildValue("(nnO)", due, pos, good ? Py_True : Py_False);
}

/* A one-dimensional (or, for ``rows`` > 0, rows × n) C-contiguous numpy array's memory, as an
 * int of 4 or 8 bytes or a double: 0 and ``view`` filled, or -1 with no error set (not such an
 * array: the caller hands the work to the Python). */
static char buffer_kind(const Py_buffer *view)
{
    const char *f = view->format ? view->format : "B";
    if (*f == '<' || *f == '=' || *f == '@')
        f++;
    if (f[0] == 0 || f[1] != 0)
        return 0;
    if (f[0] == 'd' && view->itemsize == 8)
        return 'd';
    if (f[0] == '?' && view->itemsize == 1)
        return '?';
    if ((f[0] == 'l' || f[0] == 'q' || f[0] == 'i') && (view->itemsize == 4 || view->itemsize == 8))
        return 'i';
    return 0;
}

/* numpy's array object as numpy's own header lays it out (ndarraytypes.h,
 * PyArrayObject_fields: the same from numpy 1.7 to 2.x). Asking an array for its buffer costs
 * ~1 k instructions (numpy builds the buffer's description each time), thirty times a tick: an
 * array numpy made with one of the dtypes configure_arrays was given is read from these fields
 * instead, once configure_arrays has checked them against the buffer numpy gives. */
typedef struct {
    PyObject_HEAD
    char *data;
    int nd;
    Py_ssize_t *dimensions;
    Py_ssize_t *strides;
    PyObject *base;
    PyObject *descr;
    int flags;
} np_fields;

#define NP_C_CONTIGUOUS 0x0001
#define NP_ALIGNED 0x0100
#define NP_WRITEABLE 0x0400
#define NP_WARN_ON_WRITE (1U << 31)
#define NP_DTYPES 8

static PyTypeObject *np_type; /* numpy.ndarray; NULL: every array through its buffer */
static PyObject *np_descr[NP_DTYPES];
static char np_kind[NP_DTYPES];
static Py_ssize_t np_itemsize[NP_DTYPES];
static char np_format[NP_DTYPES][2];
static int np_count;

/* The view numpy's buffer would give of ``obj`` (its kind), or 0 where only the buffer can say
 * (not a numpy array, a dtype not configured, not aligned C-contiguous, or not writable when
 * asked to be): the caller then asks for the buffer, as before. */
static char np_direct(PyObject *obj, Py_buffer *view, int writable)
{
    if (np_type == NULL || Py_TYPE(obj) != np_type)
        return 0;
    const np_fields *a = (const np_fields *)obj;
    unsigned int need = NP_C_CONTIGUOUS | NP_ALIGNED | (writable ? NP_WRITEABLE : 0);
    if (((unsigned int)a->flags & need) != need
        || (writable && ((unsigned int)a->flags & NP_WARN_ON_WRITE)) || a->nd < 0 || a->nd > 2)
        return 0;
    for (int i = 0; i < np_count; i++) {
        if (a->descr != np_descr[i])
            continue;
        Py_ssize_t len = np_itemsize[i];
        for (int d = 0; d < a->nd; d++)
            len *= a->dimensions[d];
        view->buf = a->data;
        view->obj = NULL; /* nothing to release */
        view->len = len;
        view->itemsize = np_itemsize[i];
        view->readonly = !((unsigned int)a->flags & NP_WRITEABLE);
        view->ndim = a->nd;
        view->format = np_format[i];
        view->shape = a->dimensions;
        view->strides = a->strides;
        view->suboffsets = NULL;
        view->internal = NULL;
        return np_kind[i];
    }
    return 0;
}

/* configure_arrays(ndarray, samples): the fields above checked against numpy's buffer of each
 * sample (a one-dimensional array of each dtype to read directly): True and in use, or False
 * (numpy lays its arrays out otherwise: every array through its buffer, as before). */
static PyObject *hot_configure_arrays(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    if (nargs != 2 || !PyType_Check(args[0]) || !PyTuple_CheckExact(args[1])
        || PyTuple_GET_SIZE(args[1]) > NP_DTYPES) {
        PyErr_SetString(PyExc_TypeError, "configure_arrays(ndarray, samples)");
        return NULL;
    }
    np_type = NULL;
    np_count = 0;
    PyTypeObject *type = (PyTypeObject *)args[0];
    int ok = 1;
    for (Py_ssize_t i = 0; ok && i < PyTuple_GET_SIZE(args[1]); i++) {
        PyObject *sample = PyTuple_GET_ITEM(args[1], i);
        Py_buffer v;
        if (Py_TYPE(sample) != type
            || PyObject_GetBuffer(sample, &v, PyBUF_C_CONTIGUOUS | PyBUF_FORMAT) < 0) {
            PyErr_Clear();
            ok = 0;
            break;
        }
        const np_fields *a = (const np_fields *)sample;
        PyObject *dtype = PyObject_GetAttrString(sample, "dtype");
        char kind = buffer_kind(&v);
        ok = dtype != NULL && dtype == a->descr && kind != 0 && a->data == v.buf
             && a->nd == 1 && v.ndim == 1 && a->dimensions[0] == v.shape[0] && v.shape[0] > 1
             && a->strides[0] == v.itemsize && ((unsigned int)a->flags & NP_C_CONTIGUOUS)
             && ((unsigned int)a->flags & NP_WRITEABLE) && !v.readonly;
        if (ok) {
            np_descr[np_count] = dtype; /* a dtype numpy keeps: the sample holds it, and the
                                           module keeps this reference */
            Py_INCREF(dtype);
            np_kind[np_count] = kind;
            np_itemsize[np_count] = v.itemsize;
            np_format[np_count][0] = kind == 'i' ? (v.itemsize == 8 ? 'q' : 'i') : kind;
            np_format[np_count][1] = 0;
            np_count++;
        }
        Py_XDECREF(dtype);
        PyErr_Clear();
        PyBuffer_Release(&v);
    }
    if (!ok)
        np_count = 0;
    else
        np_type = type;
    return PyBool_FromLong(ok);
}

/* The same, of whichever of the three kinds the array is (``*kind`` says which); one request
 * of the buffer where the array is not read directly (np_direct). */
static int array_any(PyObject *obj, Py_buffer *view, char *kind)
{
    if ((*kind = np_direct(obj, view, 0)) != 0)
        return 0;
    if (PyObject_GetBuffer(obj, view, PyBUF_C_CONTIGUOUS | PyBUF_FORMAT) < 0) {
        PyErr_Clear();
        return -1;
    }
    *kind = buffer_kind(view);
    if (!*kind) {
        PyBuffer_Release(view);
        return -1;
    }
    return 0;
}

static int array_view(PyObject *obj, Py_buffer *view, char kind, int writable)
{
    if (np_direct(obj, view, writable) == kind)
        return 0;
    int flags = PyBUF_C_CONTIGUOUS | PyBUF_FORMAT | (writable ? PyBUF_WRITABLE : 0);
    if (PyObject_GetBuffer(obj, view, flags) < 0) {
        PyErr_Clear();
        return -1;
    }
    if (buffer_kind(view) != kind) {
        PyBuffer_Release(view);
        return -1;
    }
    return 0;
}

static inline long long get_int(const Py_buffer *v, Py_ssize_t i)
{
    return v->itemsize == 8 ? ((const long long *)v->buf)[i] : ((const int *)v->buf)[i];
}

static inline void set_int(Py_buffer *v, Py_ssize_t i, long long x)
{
    if (v->itemsize == 8)
        ((long long *)v->buf)[i] = x;
    else
        ((int *)v->buf)[i] = (int)x;
}

/* put_ints(array, at, values): ``array[list(at)] = values`` for a one-dimensional writable
 * numpy array of ints, ``at`` a tuple of its indexes (0 … len − 1) and ``values`` a list of
 * as many ints, each fitting the array's item: True, written; NotImplemented, nothing
 * written, for anything else (the Python's then). */
static PyObject *hot_put_ints(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    if (nargs != 3) {
        PyErr_SetString(PyExc_TypeError, "put_ints takes 3 arguments");
        return NULL;
    }
    PyObject *at = args[1], *values = args[2];
    if (!PyTuple_CheckExact(at) || !PyList_CheckExact(values)
        || PyTuple_GET_SIZE(at) != PyList_GET_SIZE(values))
        Py_RETURN_NOTIMPLEMENTED;
    Py_buffer v;
    if (array_view(args[0], &v, 'i', 1) < 0)
        Py_RETURN_NOTIMPLEMENTED;
    Py_ssize_t n = PyTuple_GET_SIZE(at);
    long long lo = v.itemsize == 8 ? LLONG_MIN : INT_MIN;
    long long hi = v.itemsize == 8 ? LLONG_MAX : INT_MAX;
    int ok = v.ndim == 1;
    for (Py_ssize_t k = 0; k < n && ok; k++) {  /* everything checked before a write */
        PyObject *j = PyTuple_GET_ITEM(at, k), *x = PyList_GET_ITEM(values, k);
        if (!PyLong_CheckExact(j) || !PyLong_CheckExact(x)) {
            ok = 0;
            break;
        }
        int over = 0;
        Py_ssize_t i = PyLong_AsSsize_t(j);
        long long value = PyLong_AsLongLongAndOverflow(x, &over);
        ok = !PyErr_Occurred() && !over && i >= 0 && i < v.shape[0] && value >= lo
             && value <= hi;
    }
    PyErr_Clear();
    if (ok)
        for (Py_ssize_t k = 0; k < n; k++)
            set_int(&v, PyLong_AsSsize_t(PyTuple_GET_ITEM(at, k)),
                    PyLong_AsLongLong(PyList_GET_ITEM(values, k)));
    PyBuffer_Release(&v);
    if (!ok)
        Py_RETURN_NOTIMPLEMENTED;
    Py_RETURN_TRUE;
}

/* put_row(arrays, j, values): ``a[j] = v`` for each array ``a`` of the tuple ``arrays`` and
 * its value ``v`` of ``values``: one-dimensional writable numpy arrays of ints, doubles or
 * bools, each given a value of its own kind (an int that fits, a float, a bool). True,
 * written; NotImplemented, nothing written, for anything else (the Python's then). */
static PyObject *hot_put_row(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    if (nargs != 3) {
        PyErr_SetString(PyExc_TypeError, "put_row takes 3 arguments");
        return NULL;
    }
    PyObject *arrays = args[0], *values = args[2];
    if (!PyTuple_CheckExact(arrays) || !PyTuple_CheckExact(values) || !PyLong_CheckExact(args[1])
        || PyTuple_GET_SIZE(arrays) != PyTuple_GET_SIZE(values) || PyTuple_GET_SIZE(arrays) > 16)
        Py_RETURN_NOTIMPLEMENTED;
    Py_ssize_t j = PyLong_AsSsize_t(args[1]);
    if (j == -1 && PyErr_Occurred()) {
        PyErr_Clear();
        Py_RETURN_NOTIMPLEMENTED;
    }
    Py_ssize_t n = PyTuple_GET_SIZE(arrays);
    Py_buffer v[16];
    char kind[16];
    long long ints[16];
    int got = 0, ok = 1;
    for (; got < n && ok; got++) {  /* everything checked before a write */
        if (array_any(PyTuple_GET_ITEM(arrays, got), &v[got], &kind[got]) < 0) {
            ok = 0;
            break;
        }
        PyObject *x = PyTuple_GET_ITEM(values, got);
        ok = !v[got].readonly && v[got].ndim == 1 && j >= 0 && j < v[got].shape[0];
        if (ok && kind[got] == 'i') {
            int over = 0;
            ok = PyLong_CheckExact(x);
            ints[got] = ok ? PyLong_AsLongLongAndOverflow(x, &over) : 0;
            long long lo = v[got].itemsize == 8 ? LLONG_MIN : INT_MIN;
            long long hi = v[got].itemsize == 8 ? LLONG_MAX : INT_MAX;
            ok = ok && !over && !PyErr_Occurred() && ints[got] >= lo && ints[got] <= hi;
        } else if (ok) {
            ok = kind[got] == 'd' ? PyFloat_CheckExact(x) : PyBool_Check(x);
        }
    }
    PyErr_Clear();
    if (ok)
        for (int k = 0; k < n; k++) {
            PyObject *x = PyTuple_GET_ITEM(values, k);
            if (kind[k] == 'i')
                set_int(&v[k], j, ints[k]);
            else if (kind[k] == 'd')
                ((double *)v[k].buf)[j] = PyFloat_AS_DOUBLE(x);
            else
                ((unsigned char *)v[k].buf)[j] = x == Py_True;
        }
    for (int k = 0; k < got; k++)
        PyBuffer_Release(&v[k]);
    if (!ok)
        Py_RETURN_NOTIMPLEMENTED;
    Py_RETURN_TRUE;
}

/* imu_lists(gyro_raw, accel_raw, gyro_sign, accel_sign, c, f, pi, a, g): state.imu_lists_py
 * compiled: the gyro's s·((r − c)·f·pi/180) and the accelerometer's s·((r − c)·a·g) for each
 * of the three counts r and signs s, one operation per assignment in the Python's order (each
 * rounded to a double as each Python float operation is, -ffloat-store on i386). Two lists
 * of three floats; NotImplemented for anything else (the Python's then). */
static PyObject *hot_imu_lists(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    if (nargs != 9) {
        PyErr_SetString(PyExc_TypeError, "imu_lists takes 9 arguments");
        return NULL;
    }
    const long long big = 1LL << 40;
    long long raw[2][3], sign[2][3];
    for (int v = 0; v < 2; v++) {
        PyObject *r = args[v], *sg = args[2 + v];
        if (!PyList_CheckExact(r) || PyList_GET_SIZE(r) != 3 || !PyTuple_CheckExact(sg)
            || PyTuple_GET_SIZE(sg) != 3)
            Py_RETURN_NOTIMPLEMENTED;
        for (int k = 0; k < 3; k++) {
            PyObject *x = PyList_GET_ITEM(r, k), *y = PyTuple_GET_ITEM(sg, k);
            if (!PyLong_CheckExact(x) || !PyLong_CheckExact(y))
                Py_RETURN_NOTIMPLEMENTED;
            raw[v][k] = PyLong_AsLongLong(x);
            sign[v][k] = PyLong_AsLongLong(y);
            if (PyErr_Occurred() || raw[v][k] > big || raw[v][k] < -big || sign[v][k] > big
                || sign[v][k] < -big) {
                PyErr_Clear();
                Py_RETURN_NOTIMPLEMENTED;
            }
        }
    }
    if (!PyLong_CheckExact(args[4]) || !PyFloat_CheckExact(args[5])
        || !PyFloat_CheckExact(args[6]) || !PyFloat_CheckExact(args[7])
        || !PyFloat_CheckExact(args[8]))
        Py_RETURN_NOTIMPLEMENTED;
    long long c = PyLong_AsLongLong(args[4]);
    if (PyErr_Occurred() || c > big || c < -big) {
        PyErr_Clear();
        Py_RETURN_NOTIMPLEMENTED;
    }
    double f = PyFloat_AS_DOUBLE(args[5]), pi = PyFloat_AS_DOUBLE(args[6]);
    double a = PyFloat_AS_DOUBLE(args[7]), g = PyFloat_AS_DOUBLE(args[8]);
    PyObject *out[2] = {PyList_New(3), PyList_New(3)};
    for (int k = 0; k < 3 && out[0] != NULL && out[1] != NULL; k++) {
        double t = (double)(raw[0][k] - c);
        t = t * f;
        t = t * pi;
        t = t / 180.0;
        t = (double)sign[0][k] * t;
        PyList_SET_ITEM(out[0], k, PyFloat_FromDouble(t));
        double u = (double)(raw[1][k] - c);
        u = u * a;
        u = u * g;
        u = (double)sign[1][k] * u;
        PyList_SET_ITEM(out[1], k, PyFloat_FromDouble(u));
    }
    for (int v = 0; v < 2; v++)
        for (int k = 0; k < 3 && out[v] != NULL; k++)
            if (PyList_GET_ITEM(out[v], k) == NULL) {
                Py_CLEAR(out[v]);
                break;
            }
    if (out[0] == NULL || out[1] == NULL) {
        Py_XDECREF(out[0]);
        Py_XDECREF(out[1]);
        return NULL;
    }
    PyObject *res = PyTuple_Pack(2, out[0], out[1]);
    Py_DECREF(out[0]);
    Py_DECREF(out[1]);
    return res;
}

/* imu_arrays(block, need, gyro_at, accel_at, gyro_sign, accel_sign, c, f, pi, a, g,
 *            gyro_raw, accel_raw, gyro, accel):
 * the frame's IMU straight into its four arrays (state.imu_arrays_py: imu_raw, imu_si and
 * np.array of the counts): each axis's little-endian word at its byte offset in ``block``
 * (bytes of at least ``need``) into the int arrays, and imu_lists' arithmetic of them into the
 * double arrays (three each, writable). True, or NotImplemented, nothing written, for anything
 * else (the Python's then). */
static PyObject *hot_imu_arrays(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    if (nargs != 15) {
        PyErr_SetString(PyExc_TypeError, "imu_arrays takes 15 arguments");
        return NULL;
    }
    PyObject *block = args[0];
    if (!PyBytes_CheckExact(block) || !PyLong_CheckExact(args[1]))
        Py_RETURN_NOTIMPLEMENTED;
    Py_ssize_t need = PyLong_AsSsize_t(args[1]), have = PyBytes_GET_SIZE(block);
    if (need < 0 || have < need) {
        PyErr_Clear();
        Py_RETURN_NOTIMPLEMENTED;
    }
    const unsigned char *b = (const unsigned char *)PyBytes_AS_STRING(block);
    PyObject *lists[2] = {NULL, NULL};
    for (int v = 0; v < 2; v++) {
        PyObject *at = args[2 + v];
        if (!PyTuple_CheckExact(at) || PyTuple_GET_SIZE(at) != 3)
            goto refuse;
        lists[v] = PyList_New(3);
        if (lists[v] == NULL)
            goto fail;
        for (int k = 0; k < 3; k++) {
            PyObject *o = PyTuple_GET_ITEM(at, k);
            Py_ssize_t off = PyLong_CheckExact(o) ? PyLong_AsSsize_t(o) : -1;
            if (off < 0 || off + 2 > need) {
                PyErr_Clear();
                goto refuse;
            }
            PyObject *w = PyLong_FromLong(b[off] | (b[off + 1] << 8));
            if (w == NULL)
                goto fail;
            PyList_SET_ITEM(lists[v], k, w);
        }
    }
    PyObject *largs[9] = {lists[0], lists[1], args[4], args[5], args[6], args[7], args[8],
                          args[9], args[10]};
    PyObject *si = hot_imu_lists(self, largs, 9);
    if (si == NULL)
        goto fail;
    if (si == Py_NotImplemented) {
        Py_DECREF(si);
        goto refuse;
    }
    Py_buffer view[4];
    static const char kinds[4] = {'i', 'i', 'd', 'd'};
    int got = 0, ok = 1;
    for (; got < 4; got++) {
        if (array_view(args[11 + got], &view[got], kinds[got], 1) < 0) {
            ok = 0;
            break;
        }
        if (view[got].ndim != 1 || view[got].shape[0] != 3) {
            got++; /* held: released below */
            ok = 0;
            break;
        }
    }
    if (ok) {
        for (int k = 0; k < 3; k++) {
            set_int(&view[0], k, PyLong_AsLongLong(PyList_GET_ITEM(lists[0], k)));
            set_int(&view[1], k, PyLong_AsLongLong(PyList_GET_ITEM(lists[1], k)));
            ((double *)view[2].buf)[k] = PyFloat_AS_DOUBLE(
                PyList_GET_ITEM(PyTuple_GET_ITEM(si, 0), k));
            ((double *)view[3].buf)[k] = PyFloat_AS_DOUBLE(
                PyList_GET_ITEM(PyTuple_GET_ITEM(si, 1), k));
        }
    }
    for (int k = 0; k < got; k++)
        PyBuffer_Release(&view[k]);
    Py_DECREF(si);
    Py_DECREF(lists[0]);
    Py_DECREF(lists[1]);
    if (!ok)
        Py_RETURN_NOTIMPLEMENTED;
    Py_RETURN_TRUE;
refuse:
    Py_XDECREF(lists[0]);
    Py_XDECREF(lists[1]);
    Py_RETURN_NOTIMPLEMENTED;
fail:
    Py_XDECREF(lists[0]);
    Py_XDECREF(lists[1]);
    return NULL;
}

/* apply_fast(data, fast, position, speed, load, misses, at_position, at_speed, at_load, width):
 * SensorReader._apply_fast's whole-answer case compiled: each servo of ``fast``'s reply
 * (``width`` bytes of little-endian words in ``data``) into the state's integer arrays by its
 * id (the position, speed and load words at those word indexes; misses 0). True; or
 * NotImplemented, nothing written, when anything is not what that takes (the Python's then). */
static PyObject *hot_apply_fast(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    if (nargs != 10) {
        PyErr_SetString(PyExc_TypeError, "apply_fast takes 10 arguments");
        return NULL;
    }
    PyObject *data = args[0], *fast = args[1];
    if (!PyDict_CheckExact(data) || !PyList_CheckExact(fast))
        Py_RETURN_NOTIMPLEMENTED;
    long w[4];
    for (int i = 0; i < 4; i++) {
        if (!PyLong_CheckExact(args[6 + i]))
            Py_RETURN_NOTIMPLEMENTED;
        w[i] = PyLong_AsLong(args[6 + i]);
        if (w[i] < 0 || w[i] > 1024) {
            PyErr_Clear();
            Py_RETURN_NOTIMPLEMENTED;
        }
    }
    long width = w[3];
    if (width % 2 || 2 * w[0] + 2 > width || 2 * w[1] + 2 > width || 2 * w[2] + 2 > width)
        Py_RETURN_NOTIMPLEMENTED;
    Py_buffer v[4];
    int got = 0;
    for (; got < 4; got++)
        if (array_view(args[2 + got], &v[got], 'i', 1) < 0 || v[got].ndim != 1)
            break;
    PyObject *result = Py_NotImplemented;
    Py_ssize_t n = PyList_GET_SIZE(fast);
    if (got == 4) {
        Py_ssize_t slots = v[0].shape[0];
        for (int i = 1; i < 4; i++)
            if (v[i].shape[0] < slots)
                slots = v[i].shape[0];
        int ok = 1;
        for (Py_ssize_t k = 0; k < n && ok; k++) {  /* everything checked before a write */
            PyObject *jid = PyList_GET_ITEM(fast, k);
            PyObject *d = PyLong_CheckExact(jid) ? PyDict_GetItemWithError(data, jid) : NULL;
            long j = d ? PyLong_AsLong(jid) : -1;
            ok = d != NULL && PyBytes_CheckExact(d) && PyBytes_GET_SIZE(d) == width && j >= 0
                 && j < slots;
        }
        if (PyErr_Occurred())
            PyErr_Clear();
        if (ok) {
            for (Py_ssize_t k = 0; k < n; k++) {
                PyObject *jid = PyList_GET_ITEM(fast, k);
                const unsigned char *b = (const unsigned char *)PyBytes_AS_STRING(
                    PyDict_GetItem(data, jid));
                long j = PyLong_AsLong(jid);
                for (int i = 0; i < 3; i++)
                    set_int(&v[i], j, b[2 * w[i]] | (b[2 * w[i] + 1] << 8));
                set_int(&v[3], j, 0);
            }
            result = Py_True;
        }
    }
    for (int i = 0; i < got; i++)
        PyBuffer_Release(&v[i]);
    Py_INCREF(result);
    return result;
}

/* joint_arrays(position, speed, load, sign, offset, speed_table, load_table, k, c, out):
 * Calibration.joint_arrays compiled: into the rows of ``out`` (3 × n doubles), for every slot
 * j, sign·((position − c)·k − offset), sign·speed_table[speed & 0x7FF] and
 * sign·load_table[load & 0x7FF], each operation rounded to a double as numpy's are
 * (joint_angle). True; or
 * NotImplemented, nothing written, when an array is not what that takes. */
/* A joint angle as numpy computes it: on i386 numpy's loops compute in SSE2, each operation
 * rounded once to a double (Python's own floats compute on the x87 unit and round twice), so
 * this one is built for SSE2 there (the Atom has it; tests/unit/test_hotpath.py compares). */
#if defined(__i386__)
__attribute__((target("sse2,fpmath=sse"), used, noinline))
#endif
static void joint_angle(long long raw, long c, const double *k, const double *offset,
                        const double *sign, double *out)
{
    double t = (double)(raw - c);
    t = t * *k;
    t = t - *offset;
    *out = *sign * t;
}

static PyObject *hot_joint_arrays(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    if (nargs != 10) {
        PyErr_SetString(PyExc_TypeError, "joint_arrays takes 10 arguments");
        return NULL;
    }
    if (!PyFloat_CheckExact(args[7]) || !PyLong_CheckExact(args[8]))
        Py_RETURN_NOTIMPLEMENTED;
    double k = PyFloat_AS_DOUBLE(args[7]);
    long c = PyLong_AsLong(args[8]);
    if (c == -1 && PyErr_Occurred()) {
        PyErr_Clear();
        Py_RETURN_NOTIMPLEMENTED;
    }
    static const char kinds[8] = {'i', 'i', 'i', 'd', 'd', 'd', 'd', 'd'};
    Py_buffer v[8];
    int got = 0;
    for (; got < 8; got++) {
        int at = got < 7 ? got : 9;
        if (array_view(args[at], &v[got], kinds[got], got == 7) < 0)
            break;
    }
    PyObject *result = Py_NotImplemented;
    if (got == 8) {
        Py_ssize_t n = v[0].ndim == 1 ? v[0].shape[0] : -1;
        int ok = n >= 0 && v[7].ndim == 2 && v[7].shape[0] == 3 && v[7].shape[1] == n
                 && v[5].ndim == 1 && v[5].shape[0] == 2048 && v[6].ndim == 1
                 && v[6].shape[0] == 2048;
        for (int i = 1; i < 5 && ok; i++)
            ok = v[i].ndim == 1 && v[i].shape[0] == n;
        for (Py_ssize_t j = 0; j < n && ok; j++) {  /* the int minus c, exactly as numpy's */
            long long r = get_int(&v[0], j);
            ok = r < (1LL << 40) && r > -(1LL << 40);
        }
        if (ok) {
            const double *sign = v[3].buf, *offset = v[4].buf;
            const double *speed_table = v[5].buf, *load_table = v[6].buf;
            double *out = v[7].buf;
            for (Py_ssize_t j = 0; j < n; j++) {
                joint_angle(get_int(&v[0], j), c, &k, &offset[j], &sign[j], &out[j]);
                double t = speed_table[get_int(&v[1], j) & 0x7FF];
                t = sign[j] * t;
                out[n + j] = t;
                t = load_table[get_int(&v[2], j) & 0x7FF];
                t = sign[j] * t;
                out[2 * n + j] = t;
            }
            result = Py_True;
        }
    }
    for (int i = 0; i < got; i++)
        PyBuffer_Release(&v[i]);
    Py_INCREF(result);
    return result;
}

/* -- the walk's pose (WalkingModule._pose_py, with balance.gyro_feedback) -------------------- */

static int walk_ready;
static PyObject *walk_leg_ids[2];   /* right, left: each leg's six servo ids (ints) */
static double walk_leg_dirs[2][6];  /* and their directions */
static PyObject *walk_arm_ids[6];   /* 1 … 6 */
static double ARM_DEG1, ARM_DEG2, ARM_RAD[4], FEEDBACK_SIGN[8], DEG_TO_RAD, UNIT;
static long FEEDBACK_IDS[8] = {9, 10, 13, 14, 15, 16, 17, 18};
enum { NAME_TIME, NAME_LATCHED, NAME_PERIOD, NAME_SSL, NAME_SEL, NAME_SSR, NAME_SER, NAME_XMP,
       NAME_YMP, NAME_AMP, NAME_ZMP, NAME_GYRO_F, NAME_RATIO, NAME_SWING_RL, NAME_FOOT_HEIGHT,
       NAME_SWING_TD, NAME_PELVIS, NAME_ROLL_OFF, NAME_PITCH_OFF, NAME_YAW_OFF, NAME_X_OFF,
       NAME_Y_OFF, NAME_Z_OFF, NAME_HIP_PITCH, NAME_ARM_GAIN, NAME_BALANCE, NAME_FILTER,
       NAME_LIMIT, NAME_HIP_GAIN, NAME_KNEE_GAIN, NAME_APITCH_GAIN, NAME_AROLL_GAIN,
       NAME_IMU_VALID, NAME_GYRO_RAW, NAME_CENTRE, NAME_DT, NAMES };
static const char *name_text[NAMES] = {
    "time_ms", "latched", "period", "ssp_start_l", "ssp_end_l", "ssp_start_r", "ssp_end_r",
    "x_move_period", "y_move_period", "a_move_period", "z_move_period", "_gyro_f",
    "step_forward_back_ratio", "swing_right_left", "foot_height", "swing_top_down",
    "pelvis_offset", "roll_offset", "pitch_offset", "yaw_offset", "x_offset", "y_offset",
    "z_offset", "hip_pitch_offset", "arm_swing_gain", "balance_enable", "balance_filter",
    "balance_limit", "balance_hip_roll_gain", "balance_knee_gain", "balance_ankle_pitch_gain",
    "balance_ankle_roll_gain", "imu_valid", "gyro_raw", "gyro_centre", "dt"};
static PyObject *names[NAMES];

/* A Python number as the double its arithmetic with floats uses: a float, or an int a double
 * holds exactly (then int / int divides as the doubles do). -1: anything else. */
static int as_double(PyObject *o, double *out)
{
    if (PyFloat_CheckExact(o)) {
        *out = PyFloat_AS_DOUBLE(o);
        return 0;
    }
    if (PyLong_CheckExact(o)) {
        long long v = PyLong_AsLongLong(o);
        if ((v == -1 && PyErr_Occurred()) || v > (1LL << 53) || v < -(1LL << 53)) {
            PyErr_Clear();
            return -1;
        }
        *out = (double)v;
        return 0;
    }
    return -1;
}

static int attr_double(PyObject *obj, int name, double *out)
{
    PyObject *v = PyObject_GetAttr(obj, names[name]);
    if (v == NULL) {
        PyErr_Clear();
        return -1;
    }
    int r = as_double(v, out);
    Py_DECREF(v);
    return r;
}

/* configure_walk(right_ids, right_dirs, left_ids, left_dirs, arm_deg_1, arm_deg_2, arm_rad_3_6,
 * feedback_signs, deg_to_rad, unit): the gait's constants as gait.py and balance.py have them
 * (math.radians(1.0) is the factor math.radians multiplies by). */
static PyObject *hot_configure_walk(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    walk_ready = 0;
    if (nargs != 10) {
        PyErr_SetString(PyExc_TypeError, "configure_walk takes 10 arguments");
        return NULL;
    }
    long seen[256] = {0};
    for (int leg = 0; leg < 2; leg++) {
        PyObject *ids = args[2 * leg], *dirs = args[2 * leg + 1];
        if (!PyTuple_CheckExact(ids) || !PyTuple_CheckExact(dirs) || PyTuple_GET_SIZE(ids) != 6
            || PyTuple_GET_SIZE(dirs) != 6)
            Py_RETURN_FALSE;
        for (int i = 0; i < 6; i++) {
            PyObject *id = PyTuple_GET_ITEM(ids, i);
            long j = PyLong_CheckExact(id) ? PyLong_AsLong(id) : -1;
            long d = PyLong_CheckExact(PyTuple_GET_ITEM(dirs, i))
                     ? PyLong_AsLong(PyTuple_GET_ITEM(dirs, i)) : 9;
            PyErr_Clear();
            if (j < 7 || j > 255 || seen[j]++ || d < -1 || d > 1)  /* not an arm's id */
                Py_RETURN_FALSE;
            walk_leg_dirs[leg][i] = (double)d;
        }
        Py_XDECREF(walk_leg_ids[leg]);
        Py_INCREF(ids);
        walk_leg_ids[leg] = ids;
    }
    for (int k = 0; k < 8; k++)  /* the feedback's joints are legs' */
        if (!seen[FEEDBACK_IDS[k]])
            Py_RETURN_FALSE;
    if (!seen[9] || !seen[10])
        Py_RETURN_FALSE;
    PyObject *arms = args[6], *signs = args[7];
    if (!PyTuple_CheckExact(arms) || PyTuple_GET_SIZE(arms) != 4 || !PyTuple_CheckExact(signs)
        || PyTuple_GET_SIZE(signs) != 8 || !PyFloat_CheckExact(args[4])
        || !PyFloat_CheckExact(args[5]) || !PyFloat_CheckExact(args[8])
        || !PyFloat_CheckExact(args[9]))
        Py_RETURN_FALSE;
    for (int i = 0; i < 4; i++)
        if (as_double(PyTuple_GET_ITEM(arms, i), &ARM_RAD[i]) < 0)
            Py_RETURN_FALSE;
    for (int i = 0; i < 8; i++)
        if (as_double(PyTuple_GET_ITEM(signs, i), &FEEDBACK_SIGN[i]) < 0
            || (FEEDBACK_SIGN[i] != 1.0 && FEEDBACK_SIGN[i] != -1.0))
            Py_RETURN_FALSE;
    ARM_DEG1 = PyFloat_AS_DOUBLE(args[4]);
    ARM_DEG2 = PyFloat_AS_DOUBLE(args[5]);
    DEG_TO_RAD = PyFloat_AS_DOUBLE(args[8]);
    UNIT = PyFloat_AS_DOUBLE(args[9]);
    for (int i = 0; i < 6; i++) {
        if (walk_arm_ids[i] == NULL && (walk_arm_ids[i] = PyLong_FromLong(i + 1)) == NULL)
            return NULL;
    }
    for (int i = 0; i < NAMES; i++)
        if (names[i] == NULL && (names[i] = PyUnicode_InternFromString(name_text[i])) == NULL)
            return NULL;
    walk_ready = 1;
    Py_RETURN_TRUE;
}

/* math.sin, which raises where libm's gives NaN (an infinity): *raises set then, for the
 * Python to raise it */
static double py_sin(double x, int *raises)
{
    if (isinf(x))
        *raises = 1;
    return sin(x);
}

/* _wsin: mag * sin(2π / period · t − shift) + mag_shift, an operation at a time (*raises set
 * where the Python raises: a zero period, an infinite angle) */
static double wsin(double t, double period, double shift, double mag, double mag_shift,
                   int *raises)
{
    if (period == 0.0)
        *raises = 1;
    double a = 2.0 * PI;
    a = a / period;
    a = a * t;
    a = a - shift;
    double s = py_sin(a, raises);
    s = mag * s;
    return s + mag_shift;
}

/* A number of a 3-long numpy array (int or double) as a double: -1 if it is not such. */
static int array3(PyObject *arr, double *out)
{
    Py_buffer v;
    char kind;
    if (array_any(arr, &v, &kind) < 0)
        return -1;
    int kind_int = kind == 'i';
    int ok = kind != '?' && v.ndim == 1 && v.shape[0] >= 2;
    if (ok) {
        out[0] = kind_int ? (double)get_int(&v, 0) : ((double *)v.buf)[0];
        out[1] = kind_int ? (double)get_int(&v, 1) : ((double *)v.buf)[1];
        if (kind_int && (fabs(out[0]) > 9007199254740992.0 || fabs(out[1]) > 9007199254740992.0))
            ok = 0;
    }
    PyBuffer_Release(&v);
    return ok ? 0 : -1;
}

/* walk_pose(walker, params, frame, balance, limits): WalkingModule._pose_py compiled (the
 * foot and pelvis moves, both legs' IK and servo angles, the arms, balance.gyro_feedback and
 * the limit check, in the Python's order of operations and of the goals' keys). Returns
 * (goals or None, the feedback's new filtered gyro [rl, fb] or None where it did not run), or
 * NotImplemented for the Python's to do (anything not a number where it reads one, a
 * non-finite IK input, arrays not of ints or doubles). It changes nothing itself. */
static PyObject *hot_walk_pose(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    if (nargs != 5 || !walk_ready || ik_fallback == NULL)
        Py_RETURN_NOTIMPLEMENTED;
    PyObject *w = args[0], *p = args[1], *frame = args[2], *limits = args[4];
    int balance = PyObject_IsTrue(args[3]);
    if (balance < 0 || !(limits == Py_None || PyDict_CheckExact(limits))) {
        PyErr_Clear();
        Py_RETURN_NOTIMPLEMENTED;
    }
    double t, period, sl, el, sr, er, xmp, ymp, amp, zmp;
    double ratio, swing_rl, foot_height, swing_td, pelvis_deg, roll_deg, pitch_deg, yaw_deg;
    double x_off, y_off, z_off, hip_deg, arm_gain;
    if (attr_double(w, NAME_TIME, &t) || attr_double(w, NAME_PERIOD, &period)
        || attr_double(w, NAME_SSL, &sl) || attr_double(w, NAME_SEL, &el)
        || attr_double(w, NAME_SSR, &sr) || attr_double(w, NAME_SER, &er)
        || attr_double(w, NAME_XMP, &xmp) || attr_double(w, NAME_YMP, &ymp)
        || attr_double(w, NAME_AMP, &amp) || attr_double(w, NAME_ZMP, &zmp)
        || attr_double(p, NAME_RATIO, &ratio) || attr_double(p, NAME_SWING_RL, &swing_rl)
        || attr_double(p, NAME_FOOT_HEIGHT, &foot_height)
        || attr_double(p, NAME_SWING_TD, &swing_td) || attr_double(p, NAME_PELVIS, &pelvis_deg)
        || attr_double(p, NAME_ROLL_OFF, &roll_deg) || attr_double(p, NAME_PITCH_OFF, &pitch_deg)
        || attr_double(p, NAME_YAW_OFF, &yaw_deg) || attr_double(p, NAME_X_OFF, &x_off)
        || attr_double(p, NAME_Y_OFF, &y_off) || attr_double(p, NAME_Z_OFF, &z_off)
        || attr_double(p, NAME_HIP_PITCH, &hip_deg) || attr_double(p, NAME_ARM_GAIN, &arm_gain))
        Py_RETURN_NOTIMPLEMENTED;
    /* xm, ym_cmd, am_cmd = self.latched: floats only (an int's negation keeps no sign) */
    double xm, ym_cmd, am_cmd;
    {
        PyObject *latched = PyObject_GetAttr(w, names[NAME_LATCHED]);
        if (latched == NULL) {
            PyErr_Clear();
            Py_RETURN_NOTIMPLEMENTED;
        }
        int ok = PyList_CheckExact(latched) && PyList_GET_SIZE(latched) == 3;
        for (int i = 0; i < 3 && ok; i++)
            ok = PyFloat_CheckExact(PyList_GET_ITEM(latched, i));
        if (ok) {
            xm = PyFloat_AS_DOUBLE(PyList_GET_ITEM(latched, 0));
            ym_cmd = PyFloat_AS_DOUBLE(PyList_GET_ITEM(latched, 1));
            am_cmd = PyFloat_AS_DOUBLE(PyList_GET_ITEM(latched, 2));
        }
        Py_DECREF(latched);
        if (!ok)
            Py_RETURN_NOTIMPLEMENTED;
    }
    double half_pi = PI / 2.0, two_pi = 2.0 * PI, a, b;
    /* where the Python raises (a division by zero, math.sin of an infinity), it runs */
    int raises = xmp == 0.0 || ymp == 0.0 || amp == 0.0 || zmp == 0.0;
    double x_swap_amp = xm * ratio;
    double ym = ym_cmd / 2.0;
    double y_swap_amp = fabs(ym) * 0.04;
    y_swap_amp = swing_rl + y_swap_amp;
    double zm = foot_height / 2.0;
    double am = am_cmd * DEG_TO_RAD;
    am = am / 2.0;
    double x_swap = wsin(t, period / 2.0, PI, x_swap_amp, 0.0, &raises);
    double y_swap = wsin(t, period, 0.0, y_swap_amp, 0.0, &raises);
    double pi3 = PI * 3.0;
    pi3 = pi3 / 2.0;
    double z_swap = wsin(t, period / 2.0, pi3, swing_td, swing_td, &raises);
    double txy, start, extra, zl_t, zr_t;
    if (t <= sl) {
        txy = sl; start = sl; extra = 0.0; zl_t = sl; zr_t = sr;
    } else if (t <= el) {
        txy = t; start = sl; extra = 0.0; zl_t = t; zr_t = sr;
    } else if (t <= sr) {
        txy = el; start = sl; extra = 0.0; zl_t = el; zr_t = sr;
    } else if (t <= er) {
        txy = t; start = sr; extra = PI; zl_t = el; zr_t = t;
    } else {
        txy = er; start = sr; extra = PI; zl_t = el; zr_t = er;
    }
    double moves[3], periods[3] = {xmp, ymp, amp};
    for (int i = 0; i < 3; i++) {  /* sin(w·txy − (π/2 + w·start + extra)) */
        double wv = two_pi / periods[i];
        a = wv * txy;
        b = wv * start;
        b = half_pi + b;
        b = b + extra;
        a = a - b;
        moves[i] = py_sin(a, &raises);
    }
    double x_l = xm * moves[0];
    x_l = x_l + 0.0;
    double x_r = -xm;
    x_r = x_r * moves[0];
    x_r = x_r + 0.0;
    double y_l = ym * moves[1];
    y_l = y_l + fabs(ym);
    double y_r = -ym;
    y_r = y_r * moves[1];
    y_r = y_r + -fabs(ym);
    double c_l = am * moves[2];
    c_l = c_l + fabs(am);
    double c_r = -am;
    c_r = c_r * moves[2];
    c_r = c_r + -fabs(am);
    double wz = two_pi / zmp, z_l, z_r;
    a = wz * zl_t;
    b = wz * sl;
    b = half_pi + b;
    b = b + 0.0;
    a = a - b;
    z_l = py_sin(a, &raises);
    z_l = zm * z_l;
    z_l = z_l + zm;
    a = wz * zr_t;
    b = wz * sr;
    b = half_pi + b;
    b = b + 0.0;
    a = a - b;
    z_r = py_sin(a, &raises);
    z_r = zm * z_r;
    z_r = z_r + zm;

    double pelvis = pelvis_deg * DEG_TO_RAD;
    double pelvis_swing = pelvis * 0.35;
    double pel_l = 0.0, pel_r = 0.0;
    if (sl < t && t <= el) {
        double ph = two_pi / zmp;
        ph = ph * sl;
        ph = half_pi + ph;
        double m = pelvis_swing / 2.0;
        pel_l = wsin(t, zmp, ph, m, m, &raises);
        m = -pelvis;
        m = m / 2.0;
        pel_r = wsin(t, zmp, ph, m, m, &raises);
    } else if (sr < t && t <= er) {
        double ph = two_pi / zmp;
        ph = ph * sr;
        ph = half_pi + ph;
        double m = pelvis / 2.0;
        pel_l = wsin(t, zmp, ph, m, m, &raises);
        m = -pelvis_swing;
        m = m / 2.0;
        pel_r = wsin(t, zmp, ph, m, m, &raises);
    }
    double r_off = roll_deg * DEG_TO_RAD, p_off = pitch_deg * DEG_TO_RAD;
    double a_off = yaw_deg * DEG_TO_RAD;
    double mm = 0.001, y_half = y_off / 2.0, a_half = a_off / 2.0;
    double point[2][6];
    a = x_swap + x_r;  a = a + x_off;  point[0][0] = a * mm;
    a = y_swap + y_r;  a = a - y_half; point[0][1] = a * mm;
    a = z_swap + z_r;  a = a + z_off;  point[0][2] = a * mm;
    a = -r_off;        point[0][3] = a / 2.0;
    point[0][4] = p_off;
    point[0][5] = c_r - a_half;
    a = x_swap + x_l;  a = a + x_off;  point[1][0] = a * mm;
    a = y_swap + y_l;  a = a + y_half; point[1][1] = a * mm;
    a = z_swap + z_l;  a = a + z_off;  point[1][2] = a * mm;
    point[1][3] = r_off / 2.0;
    point[1][4] = p_off;
    point[1][5] = c_l + a_half;
    double hip_pitch = hip_deg * DEG_TO_RAD;
    if (raises)
        Py_RETURN_NOTIMPLEMENTED;
    /* the goals in the Python's key order: right leg, left leg, then the arms 1 … 6 */
    PyObject *keys[18];
    double vals[18];
    int n = 0, at9 = -1, at10 = -1;
    for (int leg = 0; leg < 2; leg++) {
        double out[6];
        int r = ik_core(point[leg], out);
        if (r == 2)
            Py_RETURN_NOTIMPLEMENTED;
        if (r == 1)
            return Py_BuildValue("(OO)", Py_None, Py_None);
        double shift = (leg == 0 ? 1.0 : -1.0) * hip_pitch;
        for (int i = 0; i < 6; i++) {
            double v = walk_leg_dirs[leg][i] * out[i];
            if (i == 2)
                v = v - shift;
            keys[n] = PyTuple_GET_ITEM(walk_leg_ids[leg], i);
            long j = PyLong_AsLong(keys[n]);
            at9 = j == 9 ? n : at9;
            at10 = j == 10 ? n : at10;
            vals[n++] = v;
        }
    }
    vals[at9] = vals[at9] + -pel_r;
    vals[at10] = vals[at10] + -pel_l;
    double arm = 0.0;
    if (xm != 0.0) {
        double pi15 = PI * 1.5;
        double mag = xm * arm_gain;
        arm = wsin(t, period, pi15, mag, 0.0, &raises);
        if (raises)
            Py_RETURN_NOTIMPLEMENTED;
    }
    a = ARM_DEG1 - arm;
    keys[n] = walk_arm_ids[0];
    vals[n++] = a * DEG_TO_RAD;
    a = ARM_DEG2 - arm;
    keys[n] = walk_arm_ids[1];
    vals[n++] = a * DEG_TO_RAD;
    for (int i = 0; i < 4; i++) {
        keys[n] = walk_arm_ids[2 + i];
        vals[n++] = ARM_RAD[i];
    }
    PyObject *filtered = Py_None;
    Py_INCREF(filtered);
    int enable = 0;
    if (balance) {
        PyObject *e = PyObject_GetAttr(p, names[NAME_BALANCE]);
        enable = e == NULL ? -1 : PyObject_IsTrue(e);
        Py_XDECREF(e);
        if (enable < 0) {
            PyErr_Clear();
            Py_DECREF(filtered);
            Py_RETURN_NOTIMPLEMENTED;
        }
    }
    if (balance && enable) {  /* balance.gyro_feedback */
        double r_rl = 0.0, r_fb = 0.0, dt, filter, limit_deg, gains[4], f[2];
        int fail = attr_double(frame, NAME_DT, &dt) || attr_double(p, NAME_FILTER, &filter)
                   || attr_double(p, NAME_LIMIT, &limit_deg)
                   || attr_double(p, NAME_HIP_GAIN, &gains[0])
                   || attr_double(p, NAME_KNEE_GAIN, &gains[1])
                   || attr_double(p, NAME_APITCH_GAIN, &gains[2])
                   || attr_double(p, NAME_AROLL_GAIN, &gains[3]);
        PyObject *valid = fail ? NULL : PyObject_GetAttr(frame, names[NAME_IMU_VALID]);
        int is_valid = valid == NULL ? -1 : PyObject_IsTrue(valid);
        Py_XDECREF(valid);
        fail = fail || is_valid < 0;
        if (!fail && is_valid) {
            double gyro[2], centre[2];
            PyObject *g = PyObject_GetAttr(frame, names[NAME_GYRO_RAW]);
            PyObject *c = PyObject_GetAttr(frame, names[NAME_CENTRE]);
            fail = g == NULL || c == NULL || array3(g, gyro) < 0 || array3(c, centre) < 0;
            Py_XDECREF(g);
            Py_XDECREF(c);
            if (!fail) {
                r_rl = gyro[0] - centre[0];
                r_fb = gyro[1] - centre[1];
            }
        }
        PyObject *prev = fail ? NULL : PyObject_GetAttr(w, names[NAME_GYRO_F]);
        fail = fail || prev == NULL || !PyList_CheckExact(prev) || PyList_GET_SIZE(prev) != 2
               || as_double(PyList_GET_ITEM(prev, 0), &f[0]) < 0
               || as_double(PyList_GET_ITEM(prev, 1), &f[1]) < 0;
        Py_XDECREF(prev);
        if (fail) {
            PyErr_Clear();
            Py_DECREF(filtered);
            Py_RETURN_NOTIMPLEMENTED;
        }
        double k = 1.0;
        if (!(filter <= 0.0)) {
            double q = filter + dt;
            if (q == 0.0) {
                Py_DECREF(filtered);
                Py_RETURN_NOTIMPLEMENTED;
            }
            q = dt / q;
            k = q < 1.0 ? q : 1.0;  /* min(1.0, q) */
        }
        double rl = r_rl - f[0];
        rl = rl * k;
        rl = f[0] + rl;
        double fb = r_fb - f[1];
        fb = fb * k;
        fb = f[1] + fb;
        double limit = limit_deg * DEG_TO_RAD;
        double by[8] = {rl, rl, fb, fb, fb, fb, rl, rl};
        double gain[8] = {gains[0], gains[0], gains[1], gains[1], gains[2], gains[2], gains[3],
                          gains[3]};
        for (int i = 0; i < 8; i++) {
            double v = FEEDBACK_SIGN[i] * by[i];
            v = v * gain[i];
            v = v * 4.0;
            v = v * UNIT;
            v = v < limit ? v : limit;
            v = v > -limit ? v : -limit;
            for (int q = 0; q < 12; q++)
                if (PyLong_AsLong(keys[q]) == FEEDBACK_IDS[i])
                    vals[q] = vals[q] + v;
        }
        Py_DECREF(filtered);
        filtered = Py_BuildValue("[dd]", rl, fb);
        if (filtered == NULL)
            return NULL;
    }
    int within = 1;
    if (limits != Py_None) {
        for (int q = 0; q < n && within; q++) {
            PyObject *lim = PyDict_GetItemWithError(limits, keys[q]);
            if (lim == NULL) {
                if (PyErr_Occurred()) {
                    PyErr_Clear();
                    Py_DECREF(filtered);
                    Py_RETURN_NOTIMPLEMENTED;
                }
                continue;
            }
            if (!PyTuple_CheckExact(lim) || PyTuple_GET_SIZE(lim) != 2
                || !PyFloat_CheckExact(PyTuple_GET_ITEM(lim, 0))
                || !PyFloat_CheckExact(PyTuple_GET_ITEM(lim, 1))) {
                Py_DECREF(filtered);
                Py_RETURN_NOTIMPLEMENTED;
            }
            double lo = PyFloat_AS_DOUBLE(PyTuple_GET_ITEM(lim, 0));
            double hi = PyFloat_AS_DOUBLE(PyTuple_GET_ITEM(lim, 1));
            within = lo <= vals[q] && vals[q] <= hi;
        }
    }
    if (!within) {
        PyObject *r = PyTuple_Pack(2, Py_None, filtered);
        Py_DECREF(filtered);
        return r;
    }
    PyObject *goals = PyDict_New();
    if (goals == NULL) {
        Py_DECREF(filtered);
        return NULL;
    }
    for (int q = 0; q < n; q++) {
        PyObject *v = PyFloat_FromDouble(vals[q]);
        if (v == NULL || PyDict_SetItem(goals, keys[q], v) < 0) {
            Py_XDECREF(v);
            Py_DECREF(goals);
            Py_DECREF(filtered);
            return NULL;
        }
        Py_DECREF(v);
    }
    PyObject *r = PyTuple_Pack(2, goals, filtered);
    Py_DECREF(goals);
    Py_DECREF(filtered);
    return r;
}

/* -- the tick's snapshot (engine/snapshot.take) ----------------------------------------------- */

/* A one-dimensional numpy array of doubles, ints or bools as its tolist() (NULL, no error set:
 * not such an array). */
static PyObject *array_list(PyObject *arr)
{
    Py_buffer v;
    char kind;
    if (array_any(arr, &v, &kind) < 0)
        return NULL;
    PyObject *out = v.ndim == 1 ? PyList_New(v.shape[0]) : NULL;
    for (Py_ssize_t j = 0; out != NULL && j < v.shape[0]; j++) {
        PyObject *x;
        if (kind == 'd')
            x = PyFloat_FromDouble(((double *)v.buf)[j]);
        else if (kind == 'i')
            x = PyLong_FromLongLong(get_int(&v, j));
        else {
            x = ((unsigned char *)v.buf)[j] ? Py_True : Py_False;
            Py_INCREF(x);
        }
        if (x == NULL)
            Py_CLEAR(out);
        else
            PyList_SET_ITEM(out, j, x);
    }
    PyBuffer_Release(&v);
    if (out == NULL)
        PyErr_Clear();
    return out;
}

/* snapshot_lists(arrays, goal, sign, offset, k, c): each array of the tuple ``arrays`` as its
 * tolist(), then the goals' angles as Calibration.positions_list(goal.tolist()) gives them
 * (sign and offset its lists): a tuple of the lists. NotImplemented when an array is not of
 * doubles, ints or bools, or the goals are not what positions_list takes (the Python's then). */
static PyObject *hot_snapshot_lists(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    if (nargs != 6 || !PyTuple_CheckExact(args[0]))
        Py_RETURN_NOTIMPLEMENTED;
    Py_ssize_t n = PyTuple_GET_SIZE(args[0]);
    PyObject *out = PyTuple_New(n + 1);
    if (out == NULL)
        return NULL;
    for (Py_ssize_t i = 0; i < n; i++) {
        PyObject *list = array_list(PyTuple_GET_ITEM(args[0], i));
        if (list == NULL) {
            Py_DECREF(out);
            Py_RETURN_NOTIMPLEMENTED;
        }
        PyTuple_SET_ITEM(out, i, list);
    }
    PyObject *raw = array_list(args[1]);
    PyObject *angles = NULL;
    if (raw != NULL) {
        PyObject *pargs[5] = {raw, args[2], args[3], args[4], args[5]};
        angles = hot_positions_list(self, pargs, 5);
        Py_DECREF(raw);
    }
    if (angles == NULL || angles == Py_NotImplemented) {
        Py_DECREF(out);
        if (angles == NULL) {
            if (raw != NULL)
                return NULL;  /* positions_list's own error */
            Py_RETURN_NOTIMPLEMENTED;
        }
        return angles;
    }
    PyTuple_SET_ITEM(out, n, angles);
    return out;
}

static PyMethodDef methods[] = {
    {"configure_arrays", (PyCFunction)(void (*)(void))hot_configure_arrays, METH_FASTCALL,
     "numpy's array fields checked, to read arrays without asking for their buffer"},
    {"configure_walk", (PyCFunction)(void (*)(void))hot_configure_walk, METH_FASTCALL,
     "the gait's constants for walk_pose"},
    {"walk_pose", (PyCFunction)(void (*)(void))hot_walk_pose, METH_FASTCALL,
     "WalkingModule._pose_py compiled"},
    {"snapshot_lists", (PyCFunction)(void (*)(void))hot_snapshot_lists, METH_FASTCALL,
     "engine/snapshot.take's lists, compiled"},
    {"take_whole", (PyCFunction)(void (*)(void))hot_take_whole, METH_FASTCALL,
     "bulk_receive._take_whole_py compiled"},
    {"imu_arrays", (PyCFunction)(void (*)(void))hot_imu_arrays, METH_FASTCALL,
     "state.imu_arrays_py compiled"},
    {"imu_lists", (PyCFunction)(void (*)(void))hot_imu_lists, METH_FASTCALL,
     "state.imu_lists_py compiled"},
    {"put_row", (PyCFunction)(void (*)(void))hot_put_row, METH_FASTCALL,
     "a[j] = v for each array and value"},
    {"put_ints", (PyCFunction)(void (*)(void))hot_put_ints, METH_FASTCALL,
     "array[list(at)] = values, for ints"},
    {"take_run", (PyCFunction)(void (*)(void))hot_take_run, METH_FASTCALL,
     "bulk_receive._take_run_py compiled"},
    {"apply_fast", (PyCFunction)(void (*)(void))hot_apply_fast, METH_FASTCALL,
     "SensorReader._apply_fast's whole answer into the state's arrays, compiled"},
    {"joint_arrays", (PyCFunction)(void (*)(void))hot_joint_arrays, METH_FASTCALL,
     "Calibration.joint_arrays compiled"},
    {"positions_list", (PyCFunction)(void (*)(void))hot_positions_list, METH_FASTCALL,
     "the conversion of Calibration.positions_list, compiled"},
    {"pack_fields", (PyCFunction)(void (*)(void))hot_pack_fields, METH_FASTCALL,
     "msgpack of a message's changing fields between its packed fixed bytes"},
    {"packb", hot_packb, METH_O,
     "msgpack's bytes of a message's dict (status, events), or NotImplemented"},
    {"configure_leg", hot_configure_leg, METH_VARARGS,
     "configure_leg(ankle, leg, thigh**2, calf**2, 2*thigh*calf, calf, thigh, pi, tau, "
     "fallback): the leg's lengths as the Python IK computes with them"},
    {"leg_ik_end_point", (PyCFunction)(void (*)(void))hot_leg_ik_end_point, METH_FASTCALL,
     "ik.leg_ik_end_point, compiled"},
    {"leg_servo_angles", (PyCFunction)(void (*)(void))hot_leg_servo_angles, METH_FASTCALL,
     "ik.leg_servo_angles after its side is looked up, compiled"},
    {"goals_raw", (PyCFunction)(void (*)(void))hot_goals_raw, METH_FASTCALL,
     "the conversion of Calibration.goals_raw, compiled"},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module = {
    PyModuleDef_HEAD_INIT, "_hotpath",
    "The motion tick's per-value arithmetic compiled (optional; the Python path is the "
    "definition).",
    -1, methods,
};

PyMODINIT_FUNC PyInit__hotpath(void)
{
    return PyModule_Create(&module);
}
