/* The ATmega1284P port's pin map (docs/avr.md draws it): every pin the port uses, in one place.
 *
 *   PORTA  PA0 ADC0 current sense left      PA1 ADC1 current sense right
 *          PA2 motor encoder left A         PA3 motor encoder left B      (PCINT2/3)
 *          PA4 motor encoder right A        PA5 motor encoder right B     (PCINT4/5)
 *          PA6 line sensor 0                PA7 line sensor 1
 *   PORTB  PB0..PB7 shock switches CAPTEUR_0..CAPTEUR_7 (PB5..PB7 are shared with the ISP header)
 *   PORTC  PC0 SCL                          PC1 SDA                       (TWI, address 2)
 *          PC2 free encoder left A          PC3 free encoder left B       (PCINT18/19)
 *          PC4 free encoder right A         PC5 free encoder right B      (PCINT20/21, JTAG off)
 *          PC6 line sensor 2                PC7 line sensor 3
 *   PORTD  PD0 RXD0 (free: a bootloader)    PD1 TXD0, or SLOW with two rates (below)
 *          PD2 basket contact               PD3 TICK: high while the control tick runs
 *          PD4 OC1B PWM right               PD5 OC1A PWM left             (Timer1, 20 kHz)
 *          PD6 direction left               PD7 direction right           (high = backward)
 *
 * Switches and line sensors are active low with the internal pull-ups: an unplugged sensor reads
 * "not pressed", "no line". Encoders: channel A on the lower pin, B on the upper one, A leading
 * B when the wheel rolls forward (x4 decoding, one count per edge).
 *
 * TICK and SLOW are for a scope (and the simavr harness, which follows them): TICK is high while
 * the control tick runs (with two rates, the servo: tick.c), SLOW while the slow steps run
 * (two-rate builds only, CONFIG_AVR_SLOW_SHIFT > 0; with one rate PD1 stays a free input). A
 * serial console would take PD1 back: SLOW is only a measurement.
 */
#ifndef ASSERV_AVR_PINMAP_H
#define ASSERV_AVR_PINMAP_H

#define PIN_I_LEFT_ADC 0 /* ADC channels */
#define PIN_I_RIGHT_ADC 1

/* Bits 2..5 of their port: left A, left B, right A, right B (encoder_isr.S relies on it). */
#define PIN_MOTOR_ENC_PORT PINA
#define PIN_MOTOR_ENC_MASK 0x3Cu
#define PIN_FREE_ENC_PORT PINC
#define PIN_FREE_ENC_MASK 0x3Cu

#define PIN_LINE_A_MASK 0xC0u /* PA6, PA7: line sensors 0, 1 */
#define PIN_LINE_C_MASK 0xC0u /* PC6, PC7: line sensors 2, 3 */

#define PIN_SHOCK_PORT PINB /* PB0..PB7: CAPTEUR_0..CAPTEUR_7 */

#define PIN_SLOW_BIT 1      /* PD1, two rates */
#define PIN_BASKET_BIT 2    /* PD2 */
#define PIN_TICK_BIT 3      /* PD3 */
#define PIN_PWM_RIGHT_BIT 4 /* PD4, OC1B */
#define PIN_PWM_LEFT_BIT 5  /* PD5, OC1A */
#define PIN_DIR_LEFT_BIT 6  /* PD6 */
#define PIN_DIR_RIGHT_BIT 7 /* PD7 */

#define PIN_SCL_BIT 0 /* PC0 */

#endif
