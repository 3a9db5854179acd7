/*
 * jhdecode: decodes a JPEG-HDR file with Greg Ward's panlib (radiance-org/panlib, BSD-3) and
 * writes the HDR pixels as a little-endian PFM (colour, bottom row first, scale -1), plus the
 * s2n value on stderr. Written for hdrcodec's interoperability check; it only calls panlib's
 * public JPEG-HDR API (jpeghdr.h) and contains no panlib code. See panlib-jpeghdr.sh.
 */
#include <stdio.h>
#include <stdlib.h>
#include "jpeghdr.h"

int main(int argc, char **argv)
{
	JHSAMPLE *rgb = NULL;
	int size[2] = {0, 0};
	float s2n = 0;
	FILE *out;
	int y;

	if (argc != 3) {
		fprintf(stderr, "usage: %s in.jpg out.pfm\n", argv[0]);
		return 2;
	}
	if (jpeghdr_load_memory(argv[1], &rgb, NULL, size, &s2n) != JPEG_HEADER_HDR || rgb == NULL) {
		fprintf(stderr, "%s: not read as JPEG-HDR by panlib\n", argv[1]);
		return 1;
	}
	out = fopen(argv[2], "wb");
	if (out == NULL) {
		perror(argv[2]);
		return 1;
	}
	fprintf(out, "PF\n%d %d\n-1.0\n", size[0], size[1]);
	for (y = size[1] - 1; y >= 0; y--)
		fwrite(rgb + (size_t)3 * size[0] * y, sizeof(JHSAMPLE), (size_t)3 * size[0], out);
	fclose(out);
	fprintf(stderr, "%s: %dx%d s2n=%g\n", argv[1], size[0], size[1], s2n);
	free(rgb);
	return 0;
}
