/* The in-process libultrahdr 1.4 peer of benches/ultrahdr_decode.rs and ultrahdr_encode.rs is reached through this
 * shim (`hdrcodec bench`'s libultrahdr rows use imagecodecs' Python instead: the CLI links no
 * peer). The library comes from the reference venv (imagecodecs' wheel bundles libuhdr 1.4.0
 * without its header), so the few declarations needed are written here from the documented
 * v1.4.0 public API (ultrahdr_api.h: enum values, struct layouts and signatures); nothing else
 * of the library is used.
 * - uhdr_shim_decode decodes an Ultra HDR JPEG held in memory to linear half-float RGBA
 *   (SDR white = 1.0), full HDR rendition, optionally copying the samples out. One call is one
 *   whole decode: decoder, set image, decode, (copy), release.
 * - uhdr_shim_encode encodes linear half-float RGBA (the HDR intent alone; libultrahdr tone-maps
 *   its own SDR base) to an Ultra HDR JPEG at a quality for both the base and the map, with the
 *   settings imagecodecs' ultrahdr_encode uses (the best-quality preset, a map scale factor) and
 *   copies the file out. One call is one whole encode: encoder, settings, encode, copy, release. */
#include <stddef.h>
#include <stdint.h>
#include <string.h>

/* ---- declarations of libultrahdr 1.4's public C API (the subset used) ---- */
enum { FMT_64BPP_RGBA_HALF = 4 };
enum { CT_LINEAR = 0 };
enum { CR_FULL_RANGE = 1 };
enum { HDR_IMG = 0, BASE_IMG = 2, GAIN_MAP_IMG = 3 };
enum { USAGE_BEST_QUALITY = 1 };
enum { CODEC_OK = 0 };

typedef struct {
    int error_code;
    int has_detail;
    char detail[256];
} shim_error_info;

typedef struct {
    int fmt, cg, ct, range;
    unsigned int w, h;
    void *planes[3];
    unsigned int stride[3];
} shim_raw_image;

typedef struct {
    void *data;
    size_t data_sz;
    size_t capacity;
    int cg, ct, range;
} shim_compressed_image;

typedef struct shim_codec shim_codec;

extern shim_codec *uhdr_create_decoder(void);
extern void uhdr_release_decoder(shim_codec *dec);
extern shim_error_info uhdr_dec_set_image(shim_codec *dec, shim_compressed_image *img);
extern shim_error_info uhdr_dec_set_out_img_format(shim_codec *dec, int fmt);
extern shim_error_info uhdr_dec_set_out_color_transfer(shim_codec *dec, int ct);
extern shim_error_info uhdr_decode(shim_codec *dec);
extern shim_raw_image *uhdr_get_decoded_image(shim_codec *dec);
extern shim_codec *uhdr_create_encoder(void);
extern void uhdr_release_encoder(shim_codec *enc);
extern shim_error_info uhdr_enc_set_raw_image(shim_codec *enc, shim_raw_image *img, int intent);
extern shim_error_info uhdr_enc_set_quality(shim_codec *enc, int quality, int intent);
extern shim_error_info uhdr_enc_set_gainmap_scale_factor(shim_codec *enc, int scale);
extern shim_error_info uhdr_enc_set_preset(shim_codec *enc, int preset);
extern shim_error_info uhdr_encode(shim_codec *enc);
extern shim_compressed_image *uhdr_get_encoded_stream(shim_codec *enc);

/* ---- the shim ---- */

static int failed(shim_error_info e, char *err, size_t err_len) {
    if (e.error_code == CODEC_OK)
        return 0;
    if (err && err_len) {
        const char *what = e.has_detail ? e.detail : "libultrahdr error";
        size_t n = strnlen(what, sizeof e.detail);
        if (n >= err_len)
            n = err_len - 1;
        memcpy(err, what, n);
        err[n] = 0;
    }
    return e.error_code;
}

#define TRY(call)                                                                                                  \
    do {                                                                                                           \
        rc = failed((call), err, err_len);                                                                         \
        if (rc)                                                                                                    \
            goto done;                                                                                             \
    } while (0)

/* Decodes `data` to linear half-float RGBA. Writes the size to *width, *height; if `out` is not
 * NULL, copies width*height*4 halves (rows packed) into it, refusing (-1, nothing written) if
 * they do not fit in `out_len` halves. 0 on success, libultrahdr's error code otherwise. */
int uhdr_shim_decode(const uint8_t *data, size_t len, uint16_t *out, size_t out_len, uint32_t *width,
                     uint32_t *height, char *err, size_t err_len) {
    int rc = 0;
    shim_codec *dec = uhdr_create_decoder();
    if (!dec)
        return -2;
    shim_compressed_image in = {(void *)data, len, len, -1, -1, -1};
    TRY(uhdr_dec_set_image(dec, &in));
    TRY(uhdr_dec_set_out_img_format(dec, FMT_64BPP_RGBA_HALF));
    TRY(uhdr_dec_set_out_color_transfer(dec, CT_LINEAR));
    TRY(uhdr_decode(dec));
    shim_raw_image *img = uhdr_get_decoded_image(dec);
    if (!img || img->fmt != FMT_64BPP_RGBA_HALF) {
        rc = -3;
        goto done;
    }
    *width = img->w;
    *height = img->h;
    if (out) {
        size_t row = (size_t)img->w * 4;
        if (out_len / (row ? row : 1) < img->h) {
            rc = -1;
            goto done;
        }
        for (unsigned int y = 0; y < img->h; y++)
            memcpy(out + y * row, (const uint16_t *)img->planes[0] + (size_t)y * img->stride[0] * 4, row * 2);
    }
done:
    uhdr_release_decoder(dec);
    return rc;
}

/* Encodes `width`x`height` linear half-float RGBA `rgba` (rows packed; SDR white = 1.0) in
 * colour gamut `gamut` (0 BT.709, 1 Display P3, 2 BT.2100) at `quality` (base and map) with a map
 * `scale` times smaller per axis. Writes the file's size to *out_size; copies the file into `out`
 * if it fits in `out_cap` bytes, else returns -1 (nothing written but *out_size). 0 on success,
 * libultrahdr's error code otherwise. libultrahdr only reads `rgba`. */
int uhdr_shim_encode(const uint16_t *rgba, uint32_t width, uint32_t height, int gamut, int quality, int scale,
                     uint8_t *out, size_t out_cap, size_t *out_size, char *err, size_t err_len) {
    int rc = 0;
    shim_codec *enc = uhdr_create_encoder();
    if (!enc)
        return -2;
    shim_raw_image img = {FMT_64BPP_RGBA_HALF, gamut, CT_LINEAR, CR_FULL_RANGE, width, height, {(void *)rgba, 0, 0},
                          {width, 0, 0}};
    TRY(uhdr_enc_set_preset(enc, USAGE_BEST_QUALITY));
    TRY(uhdr_enc_set_raw_image(enc, &img, HDR_IMG));
    TRY(uhdr_enc_set_quality(enc, quality, BASE_IMG));
    TRY(uhdr_enc_set_quality(enc, quality, GAIN_MAP_IMG));
    TRY(uhdr_enc_set_gainmap_scale_factor(enc, scale));
    TRY(uhdr_encode(enc));
    shim_compressed_image *file = uhdr_get_encoded_stream(enc);
    if (!file || !file->data) {
        rc = -3;
        goto done;
    }
    *out_size = file->data_sz;
    if (file->data_sz > out_cap) {
        rc = -1;
        goto done;
    }
    memcpy(out, file->data, file->data_sz);
done:
    uhdr_release_encoder(enc);
    return rc;
}
