#!/usr/bin/python3
"""Writes the hand-made seed corpus of the MAT fuzz target (tests/fuzz/corpus/mat/): tiny v5 files from SciPy's
writer (v4; uncompressed and compressed v5; vectors, scalars, integer types and the kinds of variable the reader leaves out)
and one v7.3 (HDF5) file from libmatio's own writer, since SciPy writes no v7.3.

    /usr/bin/python3 tests/fuzz/make_mat_seeds.py
"""
import os
import subprocess
import tempfile

import numpy as np
import scipy.io

out = os.path.join(os.path.dirname(os.path.abspath(__file__)), "corpus", "mat")
os.makedirs(out, exist_ok=True)

t = np.arange(5) * 1e-3
vectors = {"t": t, "x": np.sin(t * 1e3), "gtau": 35.15, "kp": np.int16(3)}
scipy.io.savemat(os.path.join(out, "v4_vectors.mat"), {"t": t, "x": np.cos(t * 1e3), "kv": 2.5}, format="4")
scipy.io.savemat(os.path.join(out, "v5_vectors.mat"), vectors, do_compression=False)
scipy.io.savemat(os.path.join(out, "v5_vectors_compressed.mat"), vectors, do_compression=True)
scipy.io.savemat(os.path.join(out, "v5_integer_row.mat"),
                 {"q": np.array([[1, -2, 3]], dtype=np.int32), "u": np.array([1, 2, 3], dtype=np.uint8),
                  "f": np.array([0.5, 1.5, 2.5], dtype=np.float32)},
                 do_compression=False, oned_as="row")
scipy.io.savemat(os.path.join(out, "v5_left_out.mat"),
                 {"v": np.array([1.0, 2.0]), "m": np.eye(2), "z": np.array([1 + 2j, 3j]), "s": "text",
                  "c": np.array([[1.0], "a"], dtype=object), "st": {"a": 1.0}, "e": np.zeros((0, 1))},
                 do_compression=False)

# v7.3: libmatio's writer (HDF5 with MATLAB's 512-byte user block).
program = r"""
#include <matio.h>
int main(int argc, char** argv) {
    mat_t* file = Mat_CreateVer(argv[1], NULL, MAT_FT_MAT73);
    if (file == NULL) return 1;
    double t[4] = {0.0, 0.001, 0.002, 0.003}, x[4] = {1.0, -0.5, 0.25, 2.0}, kp = 3.0;
    size_t vector_dims[2] = {4, 1}, scalar_dims[2] = {1, 1};
    matvar_t* variables[3] = {
        Mat_VarCreate("t", MAT_C_DOUBLE, MAT_T_DOUBLE, 2, vector_dims, t, MAT_F_DONT_COPY_DATA),
        Mat_VarCreate("x", MAT_C_DOUBLE, MAT_T_DOUBLE, 2, vector_dims, x, MAT_F_DONT_COPY_DATA),
        Mat_VarCreate("kp", MAT_C_DOUBLE, MAT_T_DOUBLE, 2, scalar_dims, &kp, MAT_F_DONT_COPY_DATA)};
    for (int k = 0; k < 3; ++k) {
        if (Mat_VarWrite(file, variables[k], MAT_COMPRESSION_NONE) != 0) return 1;
        Mat_VarFree(variables[k]);
    }
    return Mat_Close(file);
}
"""
with tempfile.TemporaryDirectory() as scratch:
    source = os.path.join(scratch, "write73.c")
    binary = os.path.join(scratch, "write73")
    with open(source, "w") as f:
        f.write(program)
    subprocess.run(["cc", source, "-o", binary, "-lmatio"], check=True)
    subprocess.run([binary, os.path.join(out, "v73_vectors.mat")], check=True)
