/* describe SCAN_FILE PRESET: prints the scan's R-SOLiD values one per line, a blank line, then its
 * A-SOLiD values (each with 9 significant digits: the exact float). Scan files: KITTI .bin,
 * binary PCD. Example: describe 000000.bin hdl64 */
#include <stdio.h>
#include <stdlib.h>

#include <solid.h>

#include "scan_file.h"

/* Prints what failed and solid's message for it. */
static int fail(const char *what) {
  fprintf(stderr, "describe: %s: %s\n", what, solid_last_error());
  return 1;
}

int main(int argc, char **argv) {
  SolidConfig *config = NULL;
  SolidDescriber *describer = NULL;
  ScanFile scan = {0};
  size_t n_range = 0, n_azimuth = 0, i;
  float *r = NULL, *a = NULL;
  char err[512];
  int rc = 1;
  if (argc != 3) {
    fprintf(stderr, "usage: describe SCAN_FILE PRESET\n");
    return 2;
  }
  if (scan_file_read(argv[1], &scan, err, sizeof err) != 0) {
    fprintf(stderr, "describe: %s\n", err);
    return 1;
  }
  if (solid_config_new(argv[2], &config) != SOLID_STATUS_OK) {
    rc = fail("preset");
    goto done;
  }
  if (solid_config_lengths(config, &n_range, &n_azimuth) != SOLID_STATUS_OK ||
      solid_describer_new(config, &describer) != SOLID_STATUS_OK) {
    rc = fail("config");
    goto done;
  }
  r = (float *)malloc(n_range * sizeof *r);
  a = (float *)malloc(n_azimuth * sizeof *a);
  if (!r || !a) {
    fprintf(stderr, "describe: out of memory\n");
    goto done;
  }
  /* The points are read where they are: no copy. */
  if (solid_describe(describer, &scan.points, r, n_range, a, n_azimuth, NULL) != SOLID_STATUS_OK) {
    rc = fail(argv[1]);
    goto done;
  }
  for (i = 0; i < n_range; i++) printf("%.9g\n", r[i]);
  printf("\n");
  for (i = 0; i < n_azimuth; i++) printf("%.9g\n", a[i]);
  rc = 0;
done:
  free(r);
  free(a);
  solid_describer_free(describer);
  solid_config_free(config);
  scan_file_free(&scan);
  return rc;
}
