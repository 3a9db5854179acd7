/* The in-process jxrlib peer of benches/jxr_decode.rs and benches/jxr_encode.rs, through
 * jxrlib's public glue API (libjxrglue, libjpegxr from Debian libjxr-dev):
 * - jxrlib_shim_decode decodes a .jxr held in memory to its own pixel format (the same samples
 *   as hdrcodec_jxr::decode_raw: the pixel format's bytes, rows packed) into the caller's
 *   buffer. One call is one whole decode: stream, decoder, copy, release.
 * - jxrlib_shim_encode encodes 48bppRGBHalf or 128bppRGBFloat pixels held in memory into a
 *   .jxr in the caller's buffer, with the settings JxrEncApp uses for the same -q. One call is
 *   one whole encode: stream, encoder, WritePixels, release. */
#include <stddef.h>
#include <stdint.h>
#include <string.h>

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

/* JxrEncApp's QP indices (Y, U, V, YHP, UHP, VHP) for quality 0.0, 0.1, ..., 1.0, half-float
 * (BD_16F) and float (BD_32F) pixels: the numbers of DPK_QPS_16f and DPK_QPS_32f in jxrlib's
 * jxrencoderdecoder/JxrEncApp.c ("optimized for PSNR"), which it interpolates linearly. */
static const int QPS_16F[11][6] = {
    {148, 177, 171, 165, 187, 191}, {133, 155, 153, 147, 172, 181}, {114, 133, 138, 130, 157, 167},
    {97, 118, 120, 109, 137, 144},  {76, 98, 103, 85, 115, 121},    {63, 86, 91, 62, 96, 99},
    {46, 68, 71, 43, 73, 75},       {29, 48, 52, 27, 48, 51},       {16, 30, 35, 14, 29, 34},
    {8, 14, 17, 7, 13, 17},         {3, 5, 7, 3, 5, 6}};
static const int QPS_32F[11][6] = {
    {194, 206, 209, 204, 211, 217}, {175, 187, 196, 186, 193, 205}, {157, 170, 177, 167, 180, 190},
    {133, 152, 156, 144, 163, 168}, {116, 138, 142, 117, 143, 148}, {98, 120, 123, 96, 123, 126},
    {80, 99, 102, 78, 99, 102},     {65, 79, 84, 63, 79, 84},       {48, 61, 67, 45, 60, 66},
    {27, 41, 46, 24, 40, 45},       {3, 22, 24, 2, 21, 22}};

/* Encodes `height` rows of `width` pixels (`stride` bytes per row) of 48bppRGBHalf (`format`
 * 0) or 128bppRGBFloat (`format` 1) into `out` (`out_cap` bytes), with JxrEncApp's settings
 * for `quality` (1.0: lossless, QP index 1; below 1: its -q, QP indices interpolated from its
 * tables exactly as it does) and its defaults otherwise: 4:4:4, frequency order (progressive
 * mode), all subbands, one tile, scaled arithmetic chosen by the codec, resolution 96 dpi (its
 * TIFF reader's default). `overlap` -1 takes JxrEncApp's overlap for the quality (1 for
 * lossless and from 0.5 up, 2 below), else 0, 1 or 2. The pixels are only read. On success
 * `*out_len` is the file's length and 0 is returned; else jxrlib's error code (negative;
 * WMP_errBufferOverflow if `out_cap` is too small). */
int jxrlib_shim_encode(const uint8_t *pixels, size_t stride, uint32_t width, uint32_t height, int format,
                       float quality, int overlap, uint8_t *out, size_t out_cap, size_t *out_len) {
    struct WMPStream *stream = NULL;
    PKImageEncode *enc = NULL;
    CWMIStrCodecParam scp;
    ERR err = WMP_errSuccess;
    *out_len = 0;
    FailIf(format != 0 && format != 1, WMP_errInvalidArgument);
    FailIf(overlap < -1 || overlap > 2 || !(quality > 0.f && quality <= 1.f), WMP_errInvalidArgument);
    FailIf(width == 0 || height == 0 || width > INT32_MAX || height > INT32_MAX || stride > UINT32_MAX ||
               stride < (size_t)width * (format == 0 ? 6 : 16),
           WMP_errInvalidArgument);

    /* JxrEncApp's WmpEncAppInitDefaultArgs. */
    memset(&scp, 0, sizeof(scp));
    scp.cfColorFormat = YUV_444;
    scp.bdBitDepth = BD_LONG;
    scp.bfBitstreamFormat = FREQUENCY;
    scp.bProgressiveMode = TRUE;
    scp.olOverlap = OL_ONE;
    scp.cNumOfSliceMinus1H = scp.cNumOfSliceMinus1V = 0;
    scp.sbSubband = SB_ALL;
    scp.uAlphaMode = 0;
    scp.uiDefaultQPIndex = 1;
    scp.uiDefaultQPIndexAlpha = 1;
    if (overlap >= 0)
        scp.olOverlap = (OVERLAP)overlap;

    Call(CreateWS_Memory(&stream, out, out_cap));
    Call(PKImageEncode_Create_WMP(&enc));
    Call(enc->Initialize(enc, stream, &scp, sizeof(scp)));
    stream = NULL; /* the encoder's now: its Release closes it */

    /* JxrEncApp's main, after Initialize. */
    if (quality < 1.0F) {
        int qi;
        float qf;
        const int *qps;
        if (overlap < 0)
            enc->WMP.wmiSCP.olOverlap = (quality >= 0.5F || width < 2 * MB_WIDTH_PIXEL) ? OL_ONE : OL_TWO;
        enc->WMP.wmiSCP.cfColorFormat = YUV_444; /* more than 8 bits per sample */
        qi = (int)(10.f * quality);
        qf = 10.f * quality - (float)qi;
        qps = format == 0 ? QPS_16F[qi] : QPS_32F[qi];
        enc->WMP.wmiSCP.uiDefaultQPIndex = (U8)(0.5f + (float)qps[0] * (1.f - qf) + (float)(qps + 6)[0] * qf);
        enc->WMP.wmiSCP.uiDefaultQPIndexU = (U8)(0.5f + (float)qps[1] * (1.f - qf) + (float)(qps + 6)[1] * qf);
        enc->WMP.wmiSCP.uiDefaultQPIndexV = (U8)(0.5f + (float)qps[2] * (1.f - qf) + (float)(qps + 6)[2] * qf);
        enc->WMP.wmiSCP.uiDefaultQPIndexYHP = (U8)(0.5f + (float)qps[3] * (1.f - qf) + (float)(qps + 6)[3] * qf);
        enc->WMP.wmiSCP.uiDefaultQPIndexUHP = (U8)(0.5f + (float)qps[4] * (1.f - qf) + (float)(qps + 6)[4] * qf);
        enc->WMP.wmiSCP.uiDefaultQPIndexVHP = (U8)(0.5f + (float)qps[5] * (1.f - qf) + (float)(qps + 6)[5] * qf);
    } else {
        enc->WMP.wmiSCP.uiDefaultQPIndex = 1;
    }
    Call(enc->SetPixelFormat(enc, format == 0 ? GUID_PKPixelFormat48bppRGBHalf : GUID_PKPixelFormat128bppRGBFloat));
    Call(enc->SetSize(enc, (I32)width, (I32)height));
    Call(enc->SetResolution(enc, 96.f, 96.f));
    Call(enc->WritePixels(enc, height, (U8 *)pixels, (U32)stride));
    /* No alpha: the file ends with the codestream. */
    *out_len = (size_t)enc->WMP.nOffImage + (size_t)enc->WMP.nCbImage;
Cleanup:
    if (enc && enc->pStream)
        enc->Release(&enc);
    else if (enc)
        PKFree((void **)&enc);
    if (stream)
        CloseWS_Memory(&stream);
    return (int)err;
}
