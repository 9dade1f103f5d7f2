/* Result CSV rows in C (cosim.record.csvformat): the bytes Arrow's CSV writer writes for float64 columns.
 *
 * Each double is written in the shortest decimal form that reads back to the same bits (Ryu,
 * Adams, "Ryu: fast float-to-string conversion", PLDI 2018: the vendored ryu/d2s.c, its d2d
 * gives the digits and the exponent), laid out as Arrow's writer lays it out (double-
 * conversion's shortest mode, as cosim/record/csvformat.py states): positional notation for a decimal exponent from -6 to 9, no trailing ".0", else
 * d[.ddd]e+X / e-X with no leading zero in the exponent; "-0", "inf", "-inf", "nan" (any sign).
 * No Python C API: loaded with ctypes (cosim.kernel.library), which releases the GIL. */
#include "ryu/d2s.c"

#include <stddef.h>

/* The characters of one value at ``out`` (at most COSIM_CSV_VALUE_MAX); returns their count. */
static size_t format_value(double f, char *out) {
    const uint64_t bits = double_to_bits(f);
    const bool sign = (bits >> 63) != 0;
    const uint64_t mantissa = bits & ((1ull << DOUBLE_MANTISSA_BITS) - 1);
    const uint32_t exponent2 = (uint32_t) ((bits >> DOUBLE_MANTISSA_BITS) & ((1u << DOUBLE_EXPONENT_BITS) - 1));
    size_t n = 0;
    if (exponent2 == (1u << DOUBLE_EXPONENT_BITS) - 1u) {
        if (mantissa != 0) {
            memcpy(out, "nan", 3);
            return 3;
        }
        if (sign)
            out[n++] = '-';
        memcpy(out + n, "inf", 3);
        return n + 3;
    }
    if (sign)
        out[n++] = '-';
    if (exponent2 == 0 && mantissa == 0) {
        out[n++] = '0';
        return n;
    }
    floating_decimal_64 v;
    if (d2d_small_int(mantissa, exponent2, &v)) {
        for (;;) {   /* the integer's trailing zeros into the exponent, as d2s_buffered_n */
            const uint64_t q = div10(v.mantissa);
            if ((uint32_t) v.mantissa - 10 * (uint32_t) q != 0)
                break;
            v.mantissa = q;
            ++v.exponent;
        }
    } else {
        v = d2d(mantissa, exponent2);
    }
    char digits[17];
    const uint32_t length = decimalLength17(v.mantissa);
    uint64_t m = v.mantissa;
    for (uint32_t i = length; i > 0; --i) {
        digits[i - 1] = (char) ('0' + m % 10);
        m /= 10;
    }
    /* value = 0.DIGITS x 10^point; the decimal exponent of the first digit is point - 1 */
    const int32_t point = v.exponent + (int32_t) length;
    const int32_t exponent = point - 1;
    if (exponent >= -6 && exponent <= 9) {
        if (point <= 0) {
            out[n++] = '0';
            out[n++] = '.';
            memset(out + n, '0', (size_t) -point);
            n += (size_t) -point;
            memcpy(out + n, digits, length);
            return n + length;
        }
        if ((uint32_t) point >= length) {
            memcpy(out + n, digits, length);
            n += length;
            memset(out + n, '0', (size_t) point - length);
            return n + (size_t) point - length;
        }
        memcpy(out + n, digits, (size_t) point);
        n += (size_t) point;
        out[n++] = '.';
        memcpy(out + n, digits + point, length - (size_t) point);
        return n + length - (size_t) point;
    }
    out[n++] = digits[0];
    if (length > 1) {
        out[n++] = '.';
        memcpy(out + n, digits + 1, length - 1);
        n += length - 1;
    }
    out[n++] = 'e';
    out[n++] = exponent < 0 ? '-' : '+';
    uint32_t e = (uint32_t) (exponent < 0 ? -exponent : exponent);
    if (e >= 100)
        out[n++] = (char) ('0' + e / 100);
    if (e >= 10)
        out[n++] = (char) ('0' + e / 10 % 10);
    out[n++] = (char) ('0' + e % 10);
    return n;
}

/* The lines of ``rows`` x ``columns`` doubles (row-major) into ``out``, values separated by ','
 * and each line ended by '\n'; ``out`` holds at least rows * columns * COSIM_CSV_VALUE_MAX
 * bytes (cosim_csv_value_max).  Returns the number of bytes written. */
enum { COSIM_CSV_VALUE_MAX = 26 };   /* "-0.000001" + 17 digits, or "-d.16 digits" "e-324", and the separator */

int cosim_csv_value_max(void) { return COSIM_CSV_VALUE_MAX; }

size_t cosim_format_rows(const double *values, size_t rows, size_t columns, char *out) {
    size_t n = 0;
    if (columns == 0)
        return 0;
    for (size_t r = 0; r < rows; ++r) {
        for (size_t c = 0; c < columns; ++c) {
            n += format_value(values[r * columns + c], out + n);
            out[n++] = ',';
        }
        out[n - 1] = '\n';
    }
    return n;
}
