/* scan_file.h: reads one LiDAR scan file into memory as solid's SolidPoints, as the `solid`
 * command reads it: a KITTI .bin (float32 x y z intensity) or a binary PCD (x y z fields of
 * float32 or float64, any other fields). Float32 x y z that follow each other in a record are
 * read in place (the stride skips the other fields); anything else is gathered into float32
 * x y z, as the Python reader converts it. Header-only, C99 and C++. */
#ifndef SOLID_EXAMPLE_SCAN_FILE_H
#define SOLID_EXAMPLE_SCAN_FILE_H

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <solid.h>

typedef struct {
  void *buffer;       /* owned: the records (or the gathered x y z) */
  SolidPoints points; /* borrows buffer */
} ScanFile;

static void scan_file_free(ScanFile *s) {
  free(s->buffer);
  s->buffer = NULL;
}

/* The whole file in a malloc'd buffer (aligned for any type). */
static char *scan_file_slurp(const char *path, size_t *len, char *err, size_t err_len) {
  FILE *f = fopen(path, "rb");
  char *buf = NULL;
  long n;
  if (!f) {
    snprintf(err, err_len, "%s: cannot open", path);
    return NULL;
  }
  if (fseek(f, 0, SEEK_END) == 0 && (n = ftell(f)) >= 0 && fseek(f, 0, SEEK_SET) == 0) {
    buf = (char *)malloc((size_t)n + 1);
    if (buf && fread(buf, 1, (size_t)n, f) == (size_t)n) {
      buf[n] = '\0';
      *len = (size_t)n;
    } else {
      free(buf);
      buf = NULL;
    }
  }
  fclose(f);
  if (!buf) snprintf(err, err_len, "%s: cannot read", path);
  return buf;
}

static int scan_file_read_kitti(const char *path, ScanFile *out, char *err, size_t err_len) {
  size_t len = 0;
  char *buf = scan_file_slurp(path, &len, err, err_len);
  if (!buf) return -1;
  if (len % 16 != 0) {
    snprintf(err, err_len, "%s: %zu bytes is not a whole number of 16-byte KITTI points", path, len);
    free(buf);
    return -1;
  }
  out->buffer = buf;
  out->points.data = buf;
  out->points.count = len / 16;
  out->points.stride_bytes = 16;
  out->points.coord_bytes = sizeof(float);
  return 0;
}

/* Splits a header line into its words in place (at most max). */
static int scan_file_words(char *line, char **words, int max) {
  int n = 0;
  while (*line && n < max) {
    while (*line == ' ' || *line == '\t' || *line == '\r') *line++ = '\0';
    if (!*line) break;
    words[n++] = line;
    while (*line && *line != ' ' && *line != '\t' && *line != '\r') line++;
  }
  return n;
}

static int scan_file_read_pcd(const char *path, ScanFile *out, char *err, size_t err_len) {
  enum { MAXF = 64 };
  char *names[MAXF], *sizes[MAXF], *types[MAXF], *counts[MAXF];
  int nf = 0, ns = 0, nt = 0, nc = 0;
  size_t points = 0, len = 0, pos = 0;
  int have_points = 0, binary = 0;
  char *buf = scan_file_slurp(path, &len, err, err_len);
  if (!buf) return -1;
  /* Header lines up to and including DATA. */
  while (pos < len) {
    char *line = buf + pos;
    char *end = (char *)memchr(line, '\n', len - pos);
    size_t next = end ? (size_t)(end - buf) + 1 : len;
    char *words[MAXF + 1];
    int n;
    if (end) *end = '\0';
    pos = next;
    if (line[0] == '#') continue;
    n = scan_file_words(line, words, MAXF + 1);
    if (n == 0) continue;
    if (!strcmp(words[0], "FIELDS")) { nf = n - 1; memcpy(names, words + 1, sizeof(char *) * (size_t)nf); }
    else if (!strcmp(words[0], "SIZE")) { ns = n - 1; memcpy(sizes, words + 1, sizeof(char *) * (size_t)ns); }
    else if (!strcmp(words[0], "TYPE")) { nt = n - 1; memcpy(types, words + 1, sizeof(char *) * (size_t)nt); }
    else if (!strcmp(words[0], "COUNT")) { nc = n - 1; memcpy(counts, words + 1, sizeof(char *) * (size_t)nc); }
    else if (!strcmp(words[0], "POINTS") && n > 1) { points = strtoull(words[1], NULL, 10); have_points = 1; }
    else if (!strcmp(words[0], "DATA")) {
      binary = n > 1 && !strcmp(words[1], "binary");
      if (!binary) {
        snprintf(err, err_len, "%s: DATA %s: this example reads binary PCD only", path, n > 1 ? words[1] : "?");
        free(buf);
        return -1;
      }
      break;
    }
  }
  if (!binary || !have_points || nf == 0 || ns != nf || nt != nf || (nc != 0 && nc != nf)) {
    snprintf(err, err_len, "%s: not a binary PCD with FIELDS, SIZE, TYPE and POINTS", path);
    free(buf);
    return -1;
  }
  {
    size_t offset[MAXF], record = 0, ox = 0, oy = 0, oz = 0, cb = 0;
    int i, fx = -1, fy = -1, fz = -1;
    for (i = 0; i < nf; i++) {
      size_t count = nc ? strtoull(counts[i], NULL, 10) : 1;
      offset[i] = record;
      record += strtoull(sizes[i], NULL, 10) * count;
      if (!strcmp(names[i], "x")) fx = i;
      if (!strcmp(names[i], "y")) fy = i;
      if (!strcmp(names[i], "z")) fz = i;
    }
    if (fx < 0 || fy < 0 || fz < 0 || record == 0 || points > (len - pos) / record) {
      snprintf(err, err_len, "%s: no x y z fields, or fewer bytes than POINTS records", path);
      free(buf);
      return -1;
    }
    ox = offset[fx], oy = offset[fy], oz = offset[fz];
    cb = strtoull(sizes[fx], NULL, 10);
    for (i = 0; i < 3; i++) {
      int f = i == 0 ? fx : i == 1 ? fy : fz;
      if (types[f][0] != 'F' || strtoull(sizes[f], NULL, 10) != cb || (cb != 4 && cb != 8)) {
        snprintf(err, err_len, "%s: x y z must all be float32 or all float64", path);
        free(buf);
        return -1;
      }
    }
    if (cb == 4 && ox % 4 == 0 && oy == ox + 4 && oz == ox + 8 && record % 4 == 0) {
      /* In place: the records, moved to the start of the (aligned) buffer. */
      memmove(buf, buf + pos, points * record);
      out->buffer = buf;
      out->points.data = buf + ox;
      out->points.count = points;
      out->points.stride_bytes = record;
      out->points.coord_bytes = sizeof(float);
      return 0;
    } else {
      float *xyz = (float *)malloc(points * 3 * sizeof(float) + 1);
      size_t k;
      if (!xyz) {
        snprintf(err, err_len, "%s: out of memory", path);
        free(buf);
        return -1;
      }
      for (k = 0; k < points; k++) {
        const char *rec = buf + pos + k * record;
        size_t o[3] = {ox, oy, oz};
        for (i = 0; i < 3; i++) {
          if (cb == 4) {
            memcpy(&xyz[3 * k + i], rec + o[i], 4);
          } else {
            double d;
            memcpy(&d, rec + o[i], 8);
            xyz[3 * k + i] = (float)d;
          }
        }
      }
      free(buf);
      out->buffer = xyz;
      out->points.data = xyz;
      out->points.count = points;
      out->points.stride_bytes = 3 * sizeof(float);
      out->points.coord_bytes = sizeof(float);
      return 0;
    }
  }
}

/* Reads `path` by its extension (.bin: KITTI, .pcd: PCD). 0 on success; else -1 and a message
 * in err. */
static int scan_file_read(const char *path, ScanFile *out, char *err, size_t err_len) {
  const char *dot = strrchr(path, '.');
  memset(out, 0, sizeof *out);
  if (dot && !strcmp(dot, ".bin")) return scan_file_read_kitti(path, out, err, err_len);
  if (dot && !strcmp(dot, ".pcd")) return scan_file_read_pcd(path, out, err, err_len);
  snprintf(err, err_len, "%s: unknown scan format (expected .bin or .pcd)", path);
  return -1;
}

#endif
