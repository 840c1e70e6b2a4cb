/* sha256_probe.c - what one SHA-256 block costs the PIC16F690 (not part of the firmware).
 *
 * `make sha256-probe` builds this alone with the firmware's sdcc flags and prints its
 * flash and RAM (tools/memory_report.py); tests/unit/bridge/test_pic_build.py runs it in
 * gpsim, checks the digest of "abc" (FIPS 180-4 example: ba7816bf ... f20015ad) and
 * counts the cycles between the two PORTA writes. It is the smallest honest form: the
 * compression function only (no padding, no HMAC), the 16-word rolling message schedule
 * (64 bytes, not 256), K[] and H0[] in code-space tables. docs/security.md compares it
 * with what the firmware leaves free.
 *
 * Maj() is written with one operator per statement on purpose: sdcc 4.2.0's pic14 port
 * computed `w = v[0] & v[1]; w ^= v[0] & v[2]; w ^= v[1] & v[2];` wrongly in its high
 * 16 bits (Maj of the first round 0x70676667 instead of 0x3a6fe667; gpsim).
 */
#include <stdint.h>

#include <pic16f690.h>

static const uint32_t K[64] = {
    0x428a2f98, 0x71374491, 0xb5c0fbcf, 0xe9b5dba5, 0x3956c25b, 0x59f111f1, 0x923f82a4, 0xab1c5ed5,
    0xd807aa98, 0x12835b01, 0x243185be, 0x550c7dc3, 0x72be5d74, 0x80deb1fe, 0x9bdc06a7, 0xc19bf174,
    0xe49b69c1, 0xefbe4786, 0x0fc19dc6, 0x240ca1cc, 0x2de92c6f, 0x4a7484aa, 0x5cb0a9dc, 0x76f988da,
    0x983e5152, 0xa831c66d, 0xb00327c8, 0xbf597fc7, 0xc6e00bf3, 0xd5a79147, 0x06ca6351, 0x14292967,
    0x27b70a85, 0x2e1b2138, 0x4d2c6dfc, 0x53380d13, 0x650a7354, 0x766a0abb, 0x81c2c92e, 0x92722c85,
    0xa2bfe8a1, 0xa81a664b, 0xc24b8b70, 0xc76c51a3, 0xd192e819, 0xd6990624, 0xf40e3585, 0x106aa070,
    0x19a4c116, 0x1e376c08, 0x2748774c, 0x34b0bcb5, 0x391c0cb3, 0x4ed8aa4a, 0x5b9cca4f, 0x682e6ff3,
    0x748f82ee, 0x78a5636f, 0x84c87814, 0x8cc70208, 0x90befffa, 0xa4506ceb, 0xbef9a3f7, 0xc67178f2};

uint32_t H[8];
uint32_t W[16];          /* the block, then the rolling message schedule */
static uint32_t v[8];

#define rotr(x, n) (((x) >> (n)) | ((x) << (32 - (n))))

void sha256_block(void)
{
    uint8_t t;
    uint8_t i;
    uint32_t t1;
    uint32_t t2;
    uint32_t w;
    uint32_t m;
    for (i = 0; i < 8; i++) {
        v[i] = H[i];
    }
    for (t = 0; t < 64; t++) {
        if (t >= 16) {
            uint32_t a = W[(uint8_t)((t + 1) & 15)];
            uint32_t b = W[(uint8_t)((t + 14) & 15)];
            W[t & 15] += (rotr(b, 17) ^ rotr(b, 19) ^ (b >> 10)) + W[(uint8_t)((t + 9) & 15)]
                       + (rotr(a, 7) ^ rotr(a, 18) ^ (a >> 3));
        }
        w = W[t & 15];
        t1 = rotr(v[4], 6);
        t1 ^= rotr(v[4], 11);
        t1 ^= rotr(v[4], 25);
        t1 += v[7];
        t2 = v[4] & v[5];
        t2 ^= ~v[4] & v[6];
        t1 += t2;
        t1 += K[t];
        t1 += w;
        t2 = rotr(v[0], 2);
        t2 ^= rotr(v[0], 13);
        t2 ^= rotr(v[0], 22);
        w = v[1];               /* Maj(a, b, c) = (a & b) | (c & (a | b)) */
        w &= v[0];
        m = v[1];
        m |= v[0];
        m &= v[2];
        w |= m;
        t2 += w;
        for (i = 7; i > 0; i--) {
            v[i] = v[(uint8_t)(i - 1)];
        }
        v[4] += t1;
        v[0] = t1 + t2;
    }
    for (i = 0; i < 8; i++) {
        H[i] += v[i];
    }
}

void main(void)
{
    /* "abc", padded: one block */
    uint8_t i;
    static const uint32_t H0[8] = {0x6a09e667, 0xbb67ae85, 0x3c6ef372, 0xa54ff53a,
                                   0x510e527f, 0x9b05688c, 0x1f83d9ab, 0x5be0cd19};
    for (i = 0; i < 8; i++) {
        H[i] = H0[i];
    }
    for (i = 0; i < 16; i++) {
        W[i] = 0;
    }
    W[0] = 0x61626380;
    W[15] = 24;
    PORTA = 1;
    sha256_block();
    PORTA = 2;
    for (;;) {
    }
}
