/* Minimal STM32F405 start-up: vector table, .data/.bss set-up, FPU on, then main(). */
#if defined(__arm__) /* built by the platform for ARM boards only */

#include <stdint.h>

extern uint32_t _sidata, _sdata, _edata, _sbss, _ebss, _estack;
extern int main(void);
void Reset_Handler(void);
void Default_Handler(void);
void SysTick_Handler(void) __attribute__((weak, alias("Default_Handler")));
void USART1_IRQHandler(void) __attribute__((weak, alias("Default_Handler")));
void TIM2_IRQHandler(void) __attribute__((weak, alias("Default_Handler")));
void EXTI0_IRQHandler(void) __attribute__((weak, alias("Default_Handler")));
void EXTI1_IRQHandler(void) __attribute__((weak, alias("Default_Handler")));
void EXTI2_IRQHandler(void) __attribute__((weak, alias("Default_Handler")));
void EXTI3_IRQHandler(void) __attribute__((weak, alias("Default_Handler")));
void EXTI4_IRQHandler(void) __attribute__((weak, alias("Default_Handler")));
void EXTI9_5_IRQHandler(void) __attribute__((weak, alias("Default_Handler")));
void EXTI15_10_IRQHandler(void) __attribute__((weak, alias("Default_Handler")));

#define SCB_CPACR (*(volatile uint32_t *)0xE000ED88u)

void Default_Handler(void)
{
    for (;;) {
    }
}

void Reset_Handler(void)
{
    uint32_t *src = &_sidata;
    for (uint32_t *dst = &_sdata; dst < &_edata;) {
        *dst++ = *src++;
    }
    for (uint32_t *dst = &_sbss; dst < &_ebss;) {
        *dst++ = 0u;
    }
    SCB_CPACR |= (0xFu << 20); /* CP10, CP11 full access: hard-float code may run */
    __asm__ volatile("dsb\n isb");
    (void)main();
    for (;;) {
    }
}

/* Cortex-M core vectors, then the STM32F405 peripheral vectors used here. */
#define IRQ_COUNT 82u
__attribute__((section(".isr_vector"), used))
void (*const g_vectors[16u + IRQ_COUNT])(void) = {
    (void (*)(void))(&_estack),
    Reset_Handler,
    Default_Handler, /* NMI */
    Default_Handler, /* HardFault */
    Default_Handler, /* MemManage */
    Default_Handler, /* BusFault */
    Default_Handler, /* UsageFault */
    0, 0, 0, 0,
    Default_Handler, /* SVCall */
    Default_Handler, /* DebugMon */
    0,
    Default_Handler, /* PendSV */
    SysTick_Handler,
    [16u + 6u] = EXTI0_IRQHandler,
    [16u + 7u] = EXTI1_IRQHandler,
    [16u + 8u] = EXTI2_IRQHandler,
    [16u + 9u] = EXTI3_IRQHandler,
    [16u + 10u] = EXTI4_IRQHandler,
    [16u + 23u] = EXTI9_5_IRQHandler,
    [16u + 28u] = TIM2_IRQHandler,
    [16u + 37u] = USART1_IRQHandler,
    [16u + 40u] = EXTI15_10_IRQHandler,
};

#endif
