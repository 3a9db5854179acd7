/* The in-process jxrlib peer of benches/jxr_decode.rs: decodes a .jxr held in memory to its own
 * pixel format (the same samples as hdrcodec_jxr::decode_raw: the pixel format's bytes, rows
 * packed) into the caller's buffer, through jxrlib's public glue API (libjxrglue, libjpegxr from
 * Debian libjxr-dev). One call is one whole decode: stream, decoder, copy, release. */
#include <stddef.h>
#include <stdint.h>

#include <JXRGlue.h>

/* A decoder over the bytes, set up to write the file's own pixel format (as JxrDecApp does
 * when the output format equals the input's): colour format, bit depth, unit size, and
 * image + alpha for formats that have alpha. */
static ERR open_decoder(const uint8_t *data, size_t len, struct WMPStream **stream, PKImageDecode **dec,
                        PKPixelInfo *pi) {
    ERR err = WMP_errSuccess;
    Call(CreateWS_Memory(stream, (void *)data, len));
    Call(PKImageDecode_Create_WMP(dec));
    Call((*dec)->Initialize(*dec, *stream));
    pi->pGUIDPixFmt = &(*dec)->guidPixFormat;
    Call(PixelFormatLookup(pi, LOOKUP_FORWARD));
    (*dec)->WMP.wmiSCP.uAlphaMode = (pi->grBit & PK_pixfmtHasAlpha) ? 2 : 0;
    (*dec)->WMP.wmiI.cfColorFormat = pi->cfColorFormat;
    (*dec)->WMP.wmiI.bdBitDepth = pi->bdBitDepth;
    (*dec)->WMP.wmiI.cBitsPerUnit = pi->cbitUnit;
    (*dec)->WMP.wmiI.cThumbnailWidth = (*dec)->WMP.wmiI.cWidth;
    (*dec)->WMP.wmiI.cThumbnailHeight = (*dec)->WMP.wmiI.cHeight;
    (*dec)->WMP.wmiI.bSkipFlexbits = FALSE;
    (*dec)->WMP.wmiI.cROILeftX = 0;
    (*dec)->WMP.wmiI.cROITopY = 0;
    (*dec)->WMP.wmiI.cROIWidth = (*dec)->WMP.wmiI.cWidth;
    (*dec)->WMP.wmiI.cROIHeight = (*dec)->WMP.wmiI.cHeight;
Cleanup:
    return err;
}

static void close_decoder(struct WMPStream **stream, PKImageDecode **dec) {
    if (*dec)
        (*dec)->Release(dec);
    if (*stream)
        CloseWS_Memory(stream);
}

/* Width, height and bits per pixel of the file's pixel format; 0 on success, jxrlib's error
 * code (negative) otherwise. */
int jxrlib_shim_info(const uint8_t *data, size_t len, uint32_t *width, uint32_t *height, uint32_t *bits_per_pixel) {
    struct WMPStream *stream = NULL;
    PKImageDecode *dec = NULL;
    PKPixelInfo pi = {0};
    ERR err = WMP_errSuccess;
    I32 w = 0, h = 0;
    Call(open_decoder(data, len, &stream, &dec, &pi));
    Call(dec->GetSize(dec, &w, &h));
    *width = (uint32_t)w;
    *height = (uint32_t)h;
    *bits_per_pixel = pi.cbitUnit;
Cleanup:
    close_decoder(&stream, &dec);
    return (int)err;
}

/* Decodes the whole image into `out` (`stride` bytes per row, `out_len` bytes in all); 0 on
 * success, jxrlib's error code otherwise (-1 if the buffer is too small). */
int jxrlib_shim_decode(const uint8_t *data, size_t len, uint8_t *out, size_t out_len, size_t stride) {
    struct WMPStream *stream = NULL;
    PKImageDecode *dec = NULL;
    PKPixelInfo pi = {0};
    ERR err = WMP_errSuccess;
    PKRect rect = {0, 0, 0, 0};
    Call(open_decoder(data, len, &stream, &dec, &pi));
    Call(dec->GetSize(dec, &rect.Width, &rect.Height));
    FailIf(stride > UINT32_MAX || stride * 8 < (size_t)rect.Width * pi.cbitUnit ||
               (size_t)rect.Height * stride > out_len,
           WMP_errFail);
    Call(dec->Copy(dec, &rect, out, (U32)stride));
Cleanup:
    close_decoder(&stream, &dec);
    return (int)err;
}
