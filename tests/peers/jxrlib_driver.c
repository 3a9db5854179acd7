/* A command-line driver of jxrlib_shim.c, for counting jxrlib's instructions on the same
 * decodes as ours (scripts/jxr-callgrind.sh runs it under callgrind next to the jxr_raw
 * example; the README's like-for-like instruction ratios come from there):
 *
 *   jxrlib_driver decode IN.jxr [OUT.raw]
 *       one in-process decode of IN to its own pixel format (what the bench times), the
 *       bytes optionally written to OUT (to check them against ours);
 *   jxrlib_driver encode IN.jxr OUT.jxr QUALITY half|float [OVERLAP]
 *       IN (a 48bppRGBHalf file) decoded and encoded again with JxrEncApp's settings for
 *       QUALITY (the shim's encoder): as 48bppRGBHalf, or as 128bppRGBFloat (the halves
 *       widened exactly).
 *
 * Built by the script with `cc -O2 jxrlib_driver.c jxrlib_shim.c $(pkg-config --cflags
 * --libs libjxr)`; not part of the cargo build. */
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

int jxrlib_shim_info(const uint8_t *data, size_t len, uint32_t *width, uint32_t *height, uint32_t *bits_per_pixel);
int jxrlib_shim_decode(const uint8_t *data, size_t len, uint8_t *out, size_t out_len, size_t stride);
int jxrlib_shim_encode(const uint8_t *pixels, size_t stride, uint32_t width, uint32_t height, int format,
                       float quality, int overlap, uint8_t *out, size_t out_cap, size_t *out_len);

static uint8_t *read_file(const char *path, size_t *len) {
    FILE *f = fopen(path, "rb");
    if (!f) {
        perror(path);
        exit(1);
    }
    fseek(f, 0, SEEK_END);
    long n = ftell(f);
    fseek(f, 0, SEEK_SET);
    uint8_t *data = malloc(n > 0 ? (size_t)n : 1);
    if (!data || fread(data, 1, (size_t)n, f) != (size_t)n) {
        fprintf(stderr, "%s: cannot read\n", path);
        exit(1);
    }
    fclose(f);
    *len = (size_t)n;
    return data;
}

static void write_file(const char *path, const uint8_t *data, size_t len) {
    FILE *f = fopen(path, "wb");
    if (!f || fwrite(data, 1, len, f) != len || fclose(f) != 0) {
        fprintf(stderr, "%s: cannot write\n", path);
        exit(1);
    }
}

/* Decodes `data` into a buffer of its own (rows packed); exits on an error. */
static uint8_t *decode(const uint8_t *data, size_t len, uint32_t *w, uint32_t *h, uint32_t *bits, size_t *stride) {
    int err = jxrlib_shim_info(data, len, w, h, bits);
    if (err != 0) {
        fprintf(stderr, "jxrlib: info failed (%d)\n", err);
        exit(1);
    }
    *stride = ((size_t)*w * *bits + 7) / 8;
    size_t size = *stride * *h;
    uint8_t *out = malloc(size ? size : 1);
    if (!out) {
        fprintf(stderr, "out of memory\n");
        exit(1);
    }
    err = jxrlib_shim_decode(data, len, out, size, *stride);
    if (err != 0) {
        fprintf(stderr, "jxrlib: decode failed (%d)\n", err);
        exit(1);
    }
    return out;
}

/* An IEEE half to float, exactly. */
static float half_to_float(uint16_t h) {
    uint32_t sign = (uint32_t)(h >> 15) << 31, exp = (h >> 10) & 31, man = h & 1023, bits;
    if (exp == 31)
        bits = sign | 0x7f800000u | (man << 13);
    else if (exp != 0)
        bits = sign | ((exp + 112) << 23) | (man << 13);
    else if (man == 0)
        bits = sign;
    else {
        exp = 113;
        while (!(man & 1024)) {
            man <<= 1;
            exp--;
        }
        bits = sign | (exp << 23) | ((man & 1023) << 13);
    }
    float f;
    memcpy(&f, &bits, 4);
    return f;
}

int main(int argc, char **argv) {
    if (argc >= 3 && strcmp(argv[1], "decode") == 0) {
        size_t len, stride;
        uint32_t w, h, bits;
        uint8_t *data = read_file(argv[2], &len);
        uint8_t *out = decode(data, len, &w, &h, &bits, &stride);
        if (argc >= 4)
            write_file(argv[3], out, stride * h);
        return 0;
    }
    if (argc >= 6 && strcmp(argv[1], "encode") == 0) {
        size_t len, stride;
        uint32_t w, h, bits;
        uint8_t *data = read_file(argv[2], &len);
        uint8_t *pixels = decode(data, len, &w, &h, &bits, &stride);
        if (bits != 48) {
            fprintf(stderr, "%s: not 48bppRGBHalf\n", argv[2]);
            return 1;
        }
        int format = strcmp(argv[5], "float") == 0;
        if (format) {
            size_t fstride = (size_t)w * 16;
            float *wide = calloc((size_t)h * w, 16);
            for (size_t y = 0; y < h; y++)
                for (size_t x = 0; x < w; x++)
                    for (size_t c = 0; c < 3; c++) {
                        uint16_t v;
                        memcpy(&v, pixels + y * stride + (x * 3 + c) * 2, 2);
                        wide[(y * w + x) * 4 + c] = half_to_float(v);
                    }
            free(pixels);
            pixels = (uint8_t *)wide;
            stride = fstride;
        }
        size_t cap = (size_t)h * stride + (1 << 20), out_len = 0;
        uint8_t *out = malloc(cap);
        int overlap = argc >= 7 ? atoi(argv[6]) : -1;
        int err = jxrlib_shim_encode(pixels, stride, w, h, format, (float)atof(argv[4]), overlap, out, cap, &out_len);
        if (err != 0) {
            fprintf(stderr, "jxrlib: encode failed (%d)\n", err);
            return 1;
        }
        write_file(argv[3], out, out_len);
        return 0;
    }
    fprintf(stderr, "usage: jxrlib_driver decode IN.jxr [OUT.raw] | encode IN.jxr OUT.jxr QUALITY half|float [OVERLAP]\n");
    return 2;
}
