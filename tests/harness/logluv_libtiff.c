/*
 * Test harness: libtiff's LogLuv codec (tif_luv.c) driven through its public API, so that
 * tests/logluv_libtiff.rs can compare hdrcodec-logluv with it. Built by that test with
 * `cc logluv_libtiff.c -ltiff`.
 *
 *   decode IN.tif OUT.raw         pixels as libtiff's SGILOGDATAFMT_FLOAT: float32 LE, Y per
 *                                 pixel (LogL) or X,Y,Z (LogLuv); prints "W H CHANNELS"
 *   stonits IN.tif                the STONITS tag as libtiff reads it (TIFFTAG_STONITS, a double),
 *                                 printed with 17 significant digits; "none" without the tag
 *   words IN.tif OUT.raw          the encoded words as uint32 LE (SGILOGDATAFMT_RAW for LogLuv,
 *                                 SGILOGDATAFMT_16BIT for LogL, zero-extended); prints "W H"
 *   encode KIND W H IN.raw OUT.tif [big]
 *                                 KIND = logl16 | logluv24 | logluv32; IN.raw float32 LE in the
 *                                 FLOAT layout; written with SGILOGENCODE_NODITHER, 16 rows/strip,
 *                                 little-endian unless "big" is given
 *   time-decode IN.tif REPS       seconds per full FLOAT decode, best of REPS
 *   time-encode KIND W H IN.raw REPS
 *                                 seconds per encode to an in-memory-sized temp file, best of REPS
 */
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <tiffio.h>

static void die(const char *msg, const char *arg)
{
    fprintf(stderr, "logluv_libtiff: %s %s\n", msg, arg ? arg : "");
    exit(1);
}

static double now(void)
{
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return t.tv_sec + t.tv_nsec * 1e-9;
}

/* Reads every scanline of IN in data format FMT into one buffer; returns it and its geometry. */
static unsigned char *read_all(const char *path, int fmt, uint32_t *w, uint32_t *h, int *channels,
                               tmsize_t *line_bytes)
{
    TIFF *tif = TIFFOpen(path, "r");
    if (!tif)
        die("cannot open", path);
    uint16_t photometric = 0;
    TIFFGetField(tif, TIFFTAG_IMAGEWIDTH, w);
    TIFFGetField(tif, TIFFTAG_IMAGELENGTH, h);
    TIFFGetField(tif, TIFFTAG_PHOTOMETRIC, &photometric);
    int logl = photometric == PHOTOMETRIC_LOGL;
    if (fmt == SGILOGDATAFMT_RAW && logl)
        fmt = SGILOGDATAFMT_16BIT; /* libtiff's raw form of LogL */
    if (!TIFFSetField(tif, TIFFTAG_SGILOGDATAFMT, fmt))
        die("not a LogLuv TIFF:", path);
    *channels = (fmt == SGILOGDATAFMT_FLOAT && !logl) ? 3 : 1;
    *line_bytes = TIFFScanlineSize(tif);
    unsigned char *buf = malloc((size_t)*line_bytes * *h);
    if (!buf)
        die("out of memory", NULL);
    for (uint32_t y = 0; y < *h; y++)
        if (TIFFReadScanline(tif, buf + (size_t)y * *line_bytes, y, 0) < 0)
            die("cannot read a scanline of", path);
    TIFFClose(tif);
    return buf;
}

static void write_file(const char *path, const void *data, size_t n)
{
    FILE *f = fopen(path, "wb");
    if (!f || fwrite(data, 1, n, f) != n || fclose(f))
        die("cannot write", path);
}

static float *read_floats(const char *path, size_t n)
{
    float *v = malloc(n * sizeof(float));
    FILE *f = fopen(path, "rb");
    if (!v || !f || fread(v, sizeof(float), n, f) != n)
        die("cannot read floats from", path);
    fclose(f);
    return v;
}

static int kind_channels(const char *kind)
{
    return strcmp(kind, "logl16") == 0 ? 1 : 3;
}

static void encode(const char *kind, uint32_t w, uint32_t h, const float *px, const char *out, int big)
{
    TIFF *tif = TIFFOpen(out, big ? "wb" : "wl");
    if (!tif)
        die("cannot create", out);
    int channels = kind_channels(kind);
    TIFFSetField(tif, TIFFTAG_IMAGEWIDTH, w);
    TIFFSetField(tif, TIFFTAG_IMAGELENGTH, h);
    TIFFSetField(tif, TIFFTAG_PLANARCONFIG, PLANARCONFIG_CONTIG);
    TIFFSetField(tif, TIFFTAG_SAMPLESPERPIXEL, channels);
    TIFFSetField(tif, TIFFTAG_ROWSPERSTRIP, 16);
    if (strcmp(kind, "logl16") == 0) {
        TIFFSetField(tif, TIFFTAG_PHOTOMETRIC, PHOTOMETRIC_LOGL);
        TIFFSetField(tif, TIFFTAG_COMPRESSION, COMPRESSION_SGILOG);
    } else if (strcmp(kind, "logluv32") == 0) {
        TIFFSetField(tif, TIFFTAG_PHOTOMETRIC, PHOTOMETRIC_LOGLUV);
        TIFFSetField(tif, TIFFTAG_COMPRESSION, COMPRESSION_SGILOG);
    } else if (strcmp(kind, "logluv24") == 0) {
        TIFFSetField(tif, TIFFTAG_PHOTOMETRIC, PHOTOMETRIC_LOGLUV);
        TIFFSetField(tif, TIFFTAG_COMPRESSION, COMPRESSION_SGILOG24);
    } else {
        die("unknown kind", kind);
    }
    if (!TIFFSetField(tif, TIFFTAG_SGILOGDATAFMT, SGILOGDATAFMT_FLOAT) ||
        !TIFFSetField(tif, TIFFTAG_SGILOGENCODE, SGILOGENCODE_NODITHER))
        die("libtiff refused the LogLuv settings for", out);
    /* libtiff may encode in place, so hand it a copy of each row. */
    float *row = malloc((size_t)w * channels * sizeof(float));
    for (uint32_t y = 0; y < h; y++) {
        memcpy(row, px + (size_t)y * w * channels, (size_t)w * channels * sizeof(float));
        if (TIFFWriteScanline(tif, row, y, 0) < 0)
            die("cannot write a scanline of", out);
    }
    free(row);
    TIFFClose(tif);
}

int main(int argc, char **argv)
{
    if (argc >= 4 && strcmp(argv[1], "decode") == 0) {
        uint32_t w, h;
        int c;
        tmsize_t line;
        unsigned char *buf = read_all(argv[2], SGILOGDATAFMT_FLOAT, &w, &h, &c, &line);
        write_file(argv[3], buf, (size_t)w * h * c * sizeof(float));
        printf("%u %u %d\n", w, h, c);
        return 0;
    }
    if (argc >= 3 && strcmp(argv[1], "stonits") == 0) {
        TIFF *tif = TIFFOpen(argv[2], "r");
        if (!tif)
            die("cannot open", argv[2]);
        double stonits = 0;
        if (TIFFGetField(tif, TIFFTAG_STONITS, &stonits))
            printf("%.17g\n", stonits);
        else
            printf("none\n");
        TIFFClose(tif);
        return 0;
    }
    if (argc >= 4 && strcmp(argv[1], "words") == 0) {
        uint32_t w, h;
        int c;
        tmsize_t line;
        unsigned char *buf = read_all(argv[2], SGILOGDATAFMT_RAW, &w, &h, &c, &line);
        uint32_t *words = malloc((size_t)w * h * sizeof(uint32_t));
        size_t n = (size_t)w * h;
        if (line == (tmsize_t)w * 2) { /* LogL: int16 codes */
            for (size_t i = 0; i < n; i++)
                words[i] = ((uint16_t *)buf)[i];
        } else {
            memcpy(words, buf, n * sizeof(uint32_t));
        }
        write_file(argv[3], words, n * sizeof(uint32_t));
        printf("%u %u\n", w, h);
        return 0;
    }
    if (argc >= 7 && strcmp(argv[1], "encode") == 0) {
        uint32_t w = (uint32_t)atol(argv[3]), h = (uint32_t)atol(argv[4]);
        float *px = read_floats(argv[5], (size_t)w * h * kind_channels(argv[2]));
        encode(argv[2], w, h, px, argv[6], argc >= 8 && strcmp(argv[7], "big") == 0);
        return 0;
    }
    if (argc >= 4 && strcmp(argv[1], "time-decode") == 0) {
        double best = 1e30;
        for (int r = atoi(argv[3]); r > 0; r--) {
            uint32_t w, h;
            int c;
            tmsize_t line;
            double t0 = now();
            free(read_all(argv[2], SGILOGDATAFMT_FLOAT, &w, &h, &c, &line));
            double t = now() - t0;
            if (t < best)
                best = t;
        }
        printf("%.9f\n", best);
        return 0;
    }
    if (argc >= 7 && strcmp(argv[1], "time-encode") == 0) {
        uint32_t w = (uint32_t)atol(argv[3]), h = (uint32_t)atol(argv[4]);
        float *px = read_floats(argv[5], (size_t)w * h * kind_channels(argv[2]));
        char out[4096];
        snprintf(out, sizeof out, "%s.timing.tif", argv[5]);
        double best = 1e30;
        for (int r = atoi(argv[6]); r > 0; r--) {
            double t0 = now();
            encode(argv[2], w, h, px, out, 0);
            double t = now() - t0;
            if (t < best)
                best = t;
        }
        remove(out);
        printf("%.9f\n", best);
        return 0;
    }
    fprintf(stderr, "usage: see the comment at the top of logluv_libtiff.c\n");
    return 2;
}
