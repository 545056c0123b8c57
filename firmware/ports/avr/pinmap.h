/* The ATmega1284P port's pin map (docs/avr.md draws it): every pin the port uses, in one place.
 *
 *   PORTA  PA0 ADC0 current sense left      PA1 ADC1 current sense right
 *          PA2 motor encoder left A         PA3 motor encoder left B      (PCINT2/3)
 *          PA4 shock switch CAPTEUR_2       PA5 shock switch CAPTEUR_3
 *          PA6 line sensor 0                PA7 line sensor 1
 *   PORTB  PB0 shock switch CAPTEUR_0       PB1 shock switch CAPTEUR_1
 *          PB2 motor encoder right A        PB3 motor encoder right B     (PCINT10/11)
 *          PB4..PB7 shock switches CAPTEUR_4..CAPTEUR_7 (PB5..PB7 are shared with the ISP header)
 *   PORTC  PC0 SCL                          PC1 SDA                       (TWI, address 2)
 *          PC2 free encoder left A          PC3 free encoder left B       (PCINT18/19, JTAG off)
 *          PC4 direction left               PC5 direction right           (high = backward)
 *          PC6 line sensor 2                PC7 line sensor 3
 *   PORTD  PD0 RXD0 (free: a bootloader)    PD1 TXD0, or SLOW with two rates (below)
 *          PD2 basket contact               PD3 TICK: high while the control tick runs
 *          PD4 OC1B PWM right               PD5 OC1A PWM left             (Timer1, 20 kHz)
 *          PD6 free encoder right A         PD7 free encoder right B      (PCINT30/31)
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

/* Each encoder on a port of its own (the pin-change interrupts are per port), A then B, so that
 * an edge's interrupt steps one counter: the motors on PA2, PA3 (left) and PB2, PB3 (right),
 * the free wheels on PC2, PC3 (left) and PD6, PD7 (right). encoder_isr.S and its tables rely on
 * these bits. */
#define PIN_MOTOR_LEFT_PORT PINA
#define PIN_MOTOR_LEFT_MASK 0x0Cu
#define PIN_MOTOR_RIGHT_PORT PINB
#define PIN_MOTOR_RIGHT_MASK 0x0Cu
#define PIN_FREE_LEFT_PORT PINC
#define PIN_FREE_LEFT_MASK 0x0Cu
#define PIN_FREE_RIGHT_PORT PIND
#define PIN_FREE_RIGHT_MASK 0xC0u

#define PIN_LINE_A_MASK 0xC0u /* PA6, PA7: line sensors 0, 1 */
#define PIN_LINE_C_MASK 0xC0u /* PC6, PC7: line sensors 2, 3 */

/* The shock switches: CAPTEUR_n on PBn, but CAPTEUR_2 and CAPTEUR_3 on PA4 and PA5 (PB2 and PB3
 * are the right motor's encoder): bits 4, 5 of port A shifted right by 2 are bits 2, 3. */
#define PIN_SHOCK_B_MASK 0xF3u
#define PIN_SHOCK_A_MASK 0x30u

#define PIN_SLOW_BIT 1      /* PD1, two rates */
#define PIN_BASKET_BIT 2    /* PD2 */
#define PIN_TICK_BIT 3      /* PD3 */
#define PIN_PWM_RIGHT_BIT 4 /* PD4, OC1B */
#define PIN_PWM_LEFT_BIT 5  /* PD5, OC1A */

#define PIN_SCL_BIT 0      /* PC0 */
#define PIN_DIR_PORT PORTC /* direction: high = backward */
#define PIN_DIR_DDR DDRC
#define PIN_DIR_LEFT_BIT 4  /* PC4 */
#define PIN_DIR_RIGHT_BIT 5 /* PC5 */

#endif
