/* The kept layouts' byte mover (viewer_bridge/lcmcodec/layout.py builds its programs).
 *
 * move(program, data) runs a move program over one message and returns the converted message as
 * new bytes, or None when the message does not fit the program (another size, a shape value that
 * differs, a value the output type cannot hold): the caller then takes the generated code, which
 * names the problem. Nothing here knows LCM or CDR; a program says everything.
 *
 * A program is one buffer of native-order uint32 records, then bytes:
 *   header    input_size, output_size, checks, runs
 *   checks    `checks` x (kind, at, count, step, arg), on the input:
 *               EQUAL    the `count` bytes at `at` equal the blob's at `arg` (a shape value);
 *               AT_MOST  the bytes at `at + i * step` (i < count) are each <= `arg` (a CDR bool
 *                        0/1; the top byte of a uint64 that LCM's int64 must hold);
 *               UTF8     the `count` bytes at `at` are UTF-8 (a string's text);
 *   runs      `runs` x (in_at, out_at, count, in_step, out_step, width, flags): `count` elements of
 *             `width` bytes copied from `in_at + i * in_step` to `out_at + i * out_step`, each
 *             reversed when flags has SWAP (LCM is big-endian, CDR little-endian here), or made 0/1
 *             when flags has NONZERO (LCM reads any bool byte but 0 as true, CDR writes 1);
 *   template  output_size bytes the output starts as (prefix, constants, zero padding and the
 *             zeros of a value widened on the way);
 *   blob      the expected bytes of the EQUAL checks.
 * A program is built by our own code, yet every record is checked against the declared sizes on
 * each call (a few comparisons per record), and the message's size against input_size: no input
 * and no program makes this read or write out of bounds; a malformed program raises ValueError.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <stdint.h>
#include <string.h>

enum { CHECK_EQUAL = 0, CHECK_AT_MOST = 1, CHECK_UTF8 = 2 };
enum { RUN_SWAP = 1, RUN_NONZERO = 2 };
enum { HEADER_WORDS = 4, CHECK_WORDS = 5, RUN_WORDS = 7 };

typedef struct {
    uint32_t input_size, output_size, checks, runs;
    const unsigned char *check_records, *run_records, *template, *blob;
    uint64_t blob_size;
} Program;

static uint32_t word(const unsigned char *record, int index) {
    uint32_t value;
    memcpy(&value, record + 4 * index, 4); /* records need not be aligned */
    return value;
}

/* Whether `count` elements of `width` bytes, `step` apart from `at`, fit in `size` bytes. Each is
 * below 2^32, so the sum is at most (2^32 - 1)^2 + 2 (2^32 - 1) = 2^64 - 1: no overflow. */
static int fits(uint64_t at, uint64_t count, uint64_t step, uint64_t width, uint64_t size) {
    return count == 0 || at + (count - 1) * step + width <= size;
}

static int malformed(const char *what) {
    PyErr_Format(PyExc_ValueError, "malformed move program: %s", what);
    return -1;
}

/* Reads the header and checks every record against the sizes it declares. */
static int parse(const unsigned char *bytes, Py_ssize_t length, Program *program) {
    if (length < 4 * HEADER_WORDS)
        return malformed("no header");
    program->input_size = word(bytes, 0);
    program->output_size = word(bytes, 1);
    program->checks = word(bytes, 2);
    program->runs = word(bytes, 3);
    uint64_t records = 4 * (HEADER_WORDS + (uint64_t)CHECK_WORDS * program->checks + (uint64_t)RUN_WORDS * program->runs);
    if (records + program->output_size > (uint64_t)length)
        return malformed("shorter than its header says");
    program->check_records = bytes + 4 * HEADER_WORDS;
    program->run_records = program->check_records + 4 * CHECK_WORDS * (uint64_t)program->checks;
    program->template = bytes + records;
    program->blob = program->template + program->output_size;
    program->blob_size = (uint64_t)length - records - program->output_size;
    for (uint32_t index = 0; index < program->checks; index++) {
        const unsigned char *check = program->check_records + 4 * CHECK_WORDS * (uint64_t)index;
        uint32_t kind = word(check, 0), at = word(check, 1), count = word(check, 2), step = word(check, 3),
                 arg = word(check, 4);
        if (kind == CHECK_EQUAL ? !fits(at, count, 1, 1, program->input_size) || !fits(arg, count, 1, 1, program->blob_size)
            : kind == CHECK_AT_MOST ? !fits(at, count, step, 1, program->input_size) || arg > 255
            : kind == CHECK_UTF8 ? !fits(at, count, 1, 1, program->input_size)
            : 1)
            return malformed("a check outside the input or of no known kind");
    }
    for (uint32_t index = 0; index < program->runs; index++) {
        const unsigned char *run = program->run_records + 4 * RUN_WORDS * (uint64_t)index;
        uint32_t count = word(run, 2), width = word(run, 5), flags = word(run, 6);
        if ((width != 1 && width != 2 && width != 4 && width != 8) || flags > RUN_NONZERO
            || (flags == RUN_NONZERO && width != 1))
            return malformed("a run of no known width or flags");
        if (!fits(word(run, 0), count, word(run, 3), width, program->input_size)
            || !fits(word(run, 1), count, word(run, 4), width, program->output_size))
            return malformed("a run outside the input or the output");
    }
    return 0;
}

/* 1: valid UTF-8, 0: not, -1: an error other than a decoding one. ASCII is checked here; anything
 * else by Python's own decoder, so that exactly what `str(text, "utf-8")` refuses is refused. */
static int is_utf8(const unsigned char *text, uint32_t count) {
    uint32_t index = 0;
    while (index < count && text[index] < 0x80)
        index++;
    if (index == count)
        return 1;
    PyObject *decoded = PyUnicode_DecodeUTF8((const char *)text, count, "strict");
    if (decoded != NULL) {
        Py_DECREF(decoded);
        return 1;
    }
    if (!PyErr_ExceptionMatches(PyExc_UnicodeDecodeError))
        return -1;
    PyErr_Clear();
    return 0;
}

/* 1: the input passes every check, 0: it does not, -1: an error is set. */
static int passes(const Program *program, const unsigned char *input) {
    for (uint32_t index = 0; index < program->checks; index++) {
        const unsigned char *check = program->check_records + 4 * CHECK_WORDS * (uint64_t)index;
        uint32_t kind = word(check, 0), at = word(check, 1), count = word(check, 2), arg = word(check, 4);
        if (kind == CHECK_EQUAL) {
            if (memcmp(input + at, program->blob + arg, count) != 0)
                return 0;
        } else if (kind == CHECK_AT_MOST) {
            uint32_t step = word(check, 3);
            for (uint32_t element = 0; element < count; element++)
                if (input[at + (uint64_t)element * step] > arg)
                    return 0;
        } else {
            int valid = is_utf8(input + at, count);
            if (valid != 1)
                return valid;
        }
    }
    return 1;
}

/* One element's bytes reversed: GCC and clang make each width one load, one bswap, one store. */
#define REVERSE_AS(type, bswap)                                                                  \
    do {                                                                                         \
        type value;                                                                              \
        memcpy(&value, from, sizeof value);                                                      \
        value = bswap(value);                                                                    \
        memcpy(to, &value, sizeof value);                                                        \
        return;                                                                                  \
    } while (0)

static void reverse(unsigned char *to, const unsigned char *from, uint32_t width) {
#if defined(__GNUC__)
    if (width == 8)
        REVERSE_AS(uint64_t, __builtin_bswap64);
    if (width == 4)
        REVERSE_AS(uint32_t, __builtin_bswap32);
    if (width == 2)
        REVERSE_AS(uint16_t, __builtin_bswap16);
#endif
    for (uint32_t index = 0; index < width; index++)
        to[index] = from[width - 1 - index];
}

static void run_moves(const Program *program, const unsigned char *input, unsigned char *output) {
    for (uint32_t index = 0; index < program->runs; index++) {
        const unsigned char *run = program->run_records + 4 * RUN_WORDS * (uint64_t)index;
        uint32_t count = word(run, 2), in_step = word(run, 3), out_step = word(run, 4), width = word(run, 5),
                 flags = word(run, 6);
        const unsigned char *from = input + word(run, 0);
        unsigned char *to = output + word(run, 1);
        if (flags == 0 && in_step == width && out_step == width) { /* one block: bytes, a string */
            memcpy(to, from, (size_t)count * width);
            continue;
        }
        for (uint32_t element = 0; element < count; element++, from += in_step, to += out_step) {
            if (flags == RUN_NONZERO)
                *to = *from != 0;
            else if (flags == RUN_SWAP)
                reverse(to, from, width);
            else
                memcpy(to, from, width);
        }
    }
}

/* Borrowed bytes of a `bytes` (the common case, no buffer to release) or of any buffer. */
static int borrow(PyObject *object, Py_buffer *view, const unsigned char **bytes, Py_ssize_t *length) {
    if (PyBytes_Check(object)) {
        view->obj = NULL;
        *bytes = (const unsigned char *)PyBytes_AS_STRING(object);
        *length = PyBytes_GET_SIZE(object);
        return 0;
    }
    view->obj = NULL; /* released only when set */
    if (PyObject_GetBuffer(object, view, PyBUF_SIMPLE) < 0)
        return -1;
    *bytes = view->buf;
    *length = view->len;
    return 0;
}

/* `input` converted by the program in `program_bytes`: new bytes, None when it does not fit, or
 * NULL with an error set (a malformed program). */
static PyObject *convert(const unsigned char *program_bytes, Py_ssize_t program_length,
                         const unsigned char *input, Py_ssize_t input_length) {
    Program program;
    if (parse(program_bytes, program_length, &program) < 0)
        return NULL;
    int fit = input_length == (Py_ssize_t)program.input_size ? passes(&program, input) : 0;
    if (fit <= 0)
        return fit < 0 ? NULL : Py_NewRef(Py_None);
    PyObject *result = PyBytes_FromStringAndSize(NULL, program.output_size);
    if (result != NULL) {
        unsigned char *output = (unsigned char *)PyBytes_AS_STRING(result);
        memcpy(output, program.template, program.output_size);
        run_moves(&program, input, output);
    }
    return result;
}

static PyObject *move(PyObject *module, PyObject *const *args, Py_ssize_t nargs) {
    (void)module;
    if (nargs != 2) {
        PyErr_SetString(PyExc_TypeError, "move(program, data) takes two arguments");
        return NULL;
    }
    Py_buffer program_view, data_view;
    const unsigned char *program_bytes, *input;
    Py_ssize_t program_length, input_length;
    if (borrow(args[0], &program_view, &program_bytes, &program_length) < 0)
        return NULL;
    if (borrow(args[1], &data_view, &input, &input_length) < 0) {
        PyBuffer_Release(&program_view); /* a no-op when obj is NULL */
        return NULL;
    }
    PyObject *result = convert(program_bytes, program_length, input, input_length);
    PyBuffer_Release(&data_view);
    PyBuffer_Release(&program_view);
    return result;
}

/* move_kept(programs, data): `data` (bytes) moved by the program `programs` (a dict by message
 * size) keeps for its size, or None when it keeps none (a size not seen, one without a program, a
 * Python layout) or the program does not fit: what a kept layout's converter does before its
 * generated code, in one call (the express path's, viewer_bridge/router/runner.py). */
static PyObject *move_kept(PyObject *module, PyObject *const *args, Py_ssize_t nargs) {
    (void)module;
    if (nargs != 2 || !PyDict_Check(args[0])) {
        PyErr_SetString(PyExc_TypeError, "move_kept(programs, data) takes a dict and the data");
        return NULL;
    }
    if (!PyBytes_CheckExact(args[1]))
        return Py_NewRef(Py_None);
    PyObject *size = PyLong_FromSsize_t(PyBytes_GET_SIZE(args[1]));
    if (size == NULL)
        return NULL;
    PyObject *program = PyDict_GetItemWithError(args[0], size); /* borrowed */
    Py_DECREF(size);
    if (program == NULL)
        return PyErr_Occurred() ? NULL : Py_NewRef(Py_None);
    if (!PyBytes_Check(program)) /* a Python layout (a tuple), or None: no program */
        return Py_NewRef(Py_None);
    Py_INCREF(program); /* held while it runs, whatever happens to the dict */
    /* both are bytes: their own buffers, nothing to borrow or release */
    PyObject *result = convert((const unsigned char *)PyBytes_AS_STRING(program), PyBytes_GET_SIZE(program),
                               (const unsigned char *)PyBytes_AS_STRING(args[1]), PyBytes_GET_SIZE(args[1]));
    Py_DECREF(program);
    return result;
}

static PyMethodDef methods[] = {
    {"move", (PyCFunction)(void (*)(void))move, METH_FASTCALL,
     "move(program, data, /) -> bytes | None: `data` converted by a move program, or None when it does not fit."},
    {"move_kept", (PyCFunction)(void (*)(void))move_kept, METH_FASTCALL,
     "move_kept(programs, data, /) -> bytes | None: `data` moved by the program kept for its size, or None."},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module = {
    PyModuleDef_HEAD_INIT,
    .m_name = "_mover",
    .m_doc = "The kept layouts' byte mover (see viewer_bridge.lcmcodec.layout).",
    .m_size = 0,
    .m_methods = methods,
};

PyMODINIT_FUNC PyInit__mover(void) {
    return PyModule_Create(&module);
}
