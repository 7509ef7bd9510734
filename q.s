	pushq	%rbp
	pushq	%r15
	pushq	%r14
	pushq	%r13
	pushq	%r12
	pushq	%rbx
	movq	272(%rsp), %r14
	movq	88(%rsp), %rbp
	movq	80(%rsp), %rax
	movq	%rdi, %r13
	cmpq	%rbp, %rax
	jge	.LBB0_100
	movq	56(%rsp), %rsi
	cmpq	$0, 96(%rsp)
	leaq	-1(%rbp), %r8
	jle	.LBB0_101
	movabsq	$.LCPI0_2, %rdx
	movabsq	$.LCPI0_0, %r9
	movabsq	$.LCPI0_1, %rdi
	movabsq	$-9187201950435737472, %rcx
	vmovapd	(%rdx), %xmm0
	vmovdqa	(%r9), %xmm1
	vmovapd	(%rdi), %xmm2
.LBB0_3:
	movq	%rax, %r11
	xorl	%edi, %edi
	movq	%r14, -48(%rsp)
	jmp	.LBB0_5
	.p2align	4
.LBB0_88:
	vxorpd	%xmm0, %xmm3, %xmm3
.LBB0_4:
	movq	248(%rsp), %rax
	movq	192(%rsp), %rcx
	leaq	1(%rdx), %rdi
	movq	(%rax,%rdx,8), %rax
	imulq	%r14, %rax
	addq	(%rcx,%rdx,8), %rax
	movq	136(%rsp), %rcx
	leaq	(%rcx,%rax,8), %rdx
	sarq	$63, %rax
	andq	144(%rsp), %rax
	movabsq	$-9187201950435737472, %rcx
	vmovsd	%xmm3, (%rdx,%rax,8)
	cmpq	%rdi, 96(%rsp)
	je	.LBB0_89
.LBB0_5:
	cmpq	%rbp, %r11
	jge	.LBB0_11
	movzbl	(%rsi,%r11), %eax
	cmpb	$33, %al
	setae	%dl
	cmpb	$10, %al
	sete	%al
	orb	%dl, %al
	jne	.LBB0_11
	movabsq	$1085102592571150095, %r12
	movq	%r11, %rdx
	.p2align	4
.LBB0_8:
	cmpq	%rdx, %r8
	je	.LBB0_112
	movzbl	1(%rsi,%rdx), %eax
	incq	%rdx
	cmpb	$32, %al
	ja	.LBB0_12
	cmpb	$10, %al
	jne	.LBB0_8
	jmp	.LBB0_12
	.p2align	4
.LBB0_11:
	movq	%r11, %rdx
	movabsq	$1085102592571150095, %r12
.LBB0_12:
	movq	$-1, %r9
	movq	%rdi, -32(%rsp)
	cmpq	%rbp, %rdx
	jge	.LBB0_113
	cmpb	$10, (%rsi,%rdx)
	je	.LBB0_113
	leaq	32(%rdx), %rax
	cmpq	64(%rsp), %rax
	jg	.LBB0_113
	movq	(%rsi,%rdx), %r15
	movq	8(%rsi,%rdx), %r10
	movabsq	$9187201950435737471, %r11
	movabsq	$6872316419617283935, %rbx
	movq	%r15, %rax
	andq	%r11, %rax
	movq	%r10, %rdi
	andq	%r11, %rdi
	addq	%rbx, %rax
	addq	%rbx, %rdi
	orq	%r15, %rax
	orq	%r10, %rdi
	andq	%rcx, %rax
	andq	%rcx, %rdi
	cmpq	%rcx, %rdi
	jne	.LBB0_17
	cmpq	%rcx, %rax
	jne	.LBB0_19
	jmp	.LBB0_113
	.p2align	4
.LBB0_17:
	cmpq	%rcx, %rax
	jne	.LBB0_19
	xorq	%rcx, %rdi
	tzcntq	%rdi, %r11
	shrl	$3, %r11d
	orq	$8, %r11
	jmp	.LBB0_20
	.p2align	4
.LBB0_19:
	xorq	%rcx, %rax
	tzcntq	%rax, %r11
	shrl	$3, %r11d
.LBB0_20:
	leal	-43(%r15), %eax
	movq	%r15, -40(%rsp)
	movq	%rdx, %r15
	movabsq	$434041037028460038, %rdi
	movabsq	$8102099357864587376, %rbx
	andb	$-3, %al
	cmpb	$1, %al
	adcq	$0, %r15
	movq	(%rsi,%r15), %rax
	leaq	(%rax,%rdi), %r10
	movq	%rax, %rdi
	andq	%rbx, %rdi
	movabsq	$9187201950435737471, %rbx
	shrq	$4, %r10
	andq	%r12, %r10
	orq	%r10, %rdi
	movabsq	$3689348814741910323, %r10
	xorq	%r10, %rdi
	addq	%rbx, %rdi
	orq	%rax, %rdi
	andq	%rcx, %rdi
	je	.LBB0_23
	tzcntq	%rdi, %rdi
	shrl	$3, %edi
	jne	.LBB0_24
	xorl	%edi, %edi
	xorl	%eax, %eax
	jmp	.LBB0_31
	.p2align	4
.LBB0_23:
	movl	$8, %edi
.LBB0_24:
	leal	(,%rdi,8), %r10d
	movabsq	$42949672960001, %rbx
	negb	%r10b
	shlxq	%r10, %rax, %rax
	movabsq	$71777214294589695, %r10
	andq	%r12, %rax
	imulq	$2561, %rax, %rax
	shrq	$8, %rax
	andq	%r10, %rax
	movabsq	$281470681808895, %r10
	imulq	$6553601, %rax, %rax
	shrq	$16, %rax
	andq	%r10, %rax
	imulq	%rbx, %rax
	shrq	$32, %rax
	cmpq	$8, %rdi
	jne	.LBB0_31
	movq	8(%rsi,%r15), %r10
	movabsq	$434041037028460038, %rdi
	leaq	(%r10,%rdi), %rbx
	movq	%r10, %rdi
	shrq	$4, %rbx
	andq	%r12, %rbx
	movabsq	$8102099357864587376, %r12
	andq	%r12, %rdi
	movabsq	$9187201950435737471, %r12
	orq	%rbx, %rdi
	movabsq	$3689348814741910323, %rbx
	xorq	%rbx, %rdi
	addq	%r12, %rdi
	orq	%r10, %rdi
	andq	%rcx, %rdi
	je	.LBB0_28
	tzcntq	%rdi, %rdi
	shrl	$3, %edi
	jne	.LBB0_29
	xorl	%edi, %edi
	xorl	%r10d, %r10d
	movabsq	$1085102592571150095, %r12
	jmp	.LBB0_30
.LBB0_28:
	movl	$8, %edi
.LBB0_29:
	leal	(,%rdi,8), %ebx
	movabsq	$1085102592571150095, %r12
	negb	%bl
	shlxq	%rbx, %r10, %r10
	movabsq	$71777214294589695, %rbx
	andq	%r12, %r10
	imulq	$2561, %r10, %r10
	shrq	$8, %r10
	andq	%rbx, %r10
	movabsq	$281470681808895, %rbx
	imulq	$6553601, %r10, %r10
	shrq	$16, %r10
	andq	%rbx, %r10
	movabsq	$42949672960001, %rbx
	imulq	%rbx, %r10
	shrq	$32, %r10
.LBB0_30:
	movabsq	$.const.array.data.3, %rbx
	imulq	(%rbx,%rdi,8), %rax
	addq	$8, %rdi
	addq	%r10, %rax
.LBB0_31:
	addq	%rdi, %r15
	cmpb	$46, (%rsi,%r15)
	jne	.LBB0_35
	movq	1(%rsi,%r15), %rbx
	movabsq	$434041037028460038, %r10
	leaq	(%rbx,%r10), %r14
	movq	%rbx, %r10
	shrq	$4, %r14
	andq	%r12, %r14
	movabsq	$8102099357864587376, %r12
	andq	%r12, %r10
	movabsq	$9187201950435737471, %r12
	orq	%r14, %r10
	movabsq	$3689348814741910323, %r14
	xorq	%r14, %r10
	addq	%r12, %r10
	orq	%rbx, %r10
	andq	%rcx, %r10
	je	.LBB0_36
	tzcntq	%r10, %r12
	shrl	$3, %r12d
	jne	.LBB0_37
	movq	-48(%rsp), %r14
	xorl	%r12d, %r12d
	jmp	.LBB0_45
	.p2align	4
.LBB0_35:
	xorl	%r12d, %r12d
	jmp	.LBB0_46
.LBB0_36:
	movl	$8, %r12d
.LBB0_37:
	leal	(,%r12,8), %r10d
	movabsq	$.const.array.data.3, %r14
	imulq	(%r10,%r14), %rax
	negb	%r10b
	movabsq	$71777214294589695, %r14
	shlxq	%r10, %rbx, %r10
	movabsq	$1085102592571150095, %rbx
	andq	%rbx, %r10
	imulq	$2561, %r10, %r10
	shrq	$8, %r10
	andq	%r14, %r10
	movabsq	$281470681808895, %r14
	imulq	$6553601, %r10, %r10
	shrq	$16, %r10
	andq	%r14, %r10
	movabsq	$42949672960001, %r14
	imulq	%r14, %r10
	shrq	$32, %r10
	addq	%r10, %rax
	cmpq	$8, %r12
	jne	.LBB0_41
	movq	9(%rsi,%r15), %r10
	movabsq	$434041037028460038, %r14
	movabsq	$8102099357864587376, %r12
	addq	%r10, %r14
	shrq	$4, %r14
	andq	%rbx, %r14
	movq	%r10, %rbx
	andq	%r12, %rbx
	movabsq	$9187201950435737471, %r12
	orq	%r14, %rbx
	movabsq	$3689348814741910323, %r14
	xorq	%r14, %rbx
	addq	%r12, %rbx
	orq	%r10, %rbx
	andq	%rcx, %rbx
	je	.LBB0_42
	tzcntq	%rbx, %r12
	shrl	$3, %r12d
	jne	.LBB0_43
	movq	-48(%rsp), %r14
	xorl	%r12d, %r12d
	xorl	%r10d, %r10d
	jmp	.LBB0_44
.LBB0_41:
	movq	-48(%rsp), %r14
	jmp	.LBB0_45
.LBB0_42:
	movl	$8, %r12d
.LBB0_43:
	leal	(,%r12,8), %ebx
	movq	-48(%rsp), %r14
	negb	%bl
	shlxq	%rbx, %r10, %r10
	movabsq	$1085102592571150095, %rbx
	andq	%rbx, %r10
	movabsq	$71777214294589695, %rbx
	imulq	$2561, %r10, %r10
	shrq	$8, %r10
	andq	%rbx, %r10
	movabsq	$281470681808895, %rbx
	imulq	$6553601, %r10, %r10
	shrq	$16, %r10
	andq	%rbx, %r10
	movabsq	$42949672960001, %rbx
	imulq	%rbx, %r10
	shrq	$32, %r10
.LBB0_44:
	movabsq	$.const.array.data.3, %rbx
	imulq	(%rbx,%r12,8), %rax
	addq	$8, %r12
	addq	%r10, %rax
.LBB0_45:
	leaq	1(%r15,%r12), %r15
	addq	%r12, %rdi
	negq	%r12
.LBB0_46:
	addl	$-20, %edi
	cmpl	$-19, %edi
	jb	.LBB0_113
	addq	%rdx, %r11
	cmpq	%r11, %r15
	jge	.LBB0_54
	movzbl	(%rsi,%r15), %edx
	andb	$-33, %dl
	cmpb	$69, %dl
	jne	.LBB0_113
	movzbl	1(%rsi,%r15), %edx
	leaq	1(%r15), %rdi
	addq	$2, %r15
	movabsq	$8102099357864587376, %rbp
	leal	-43(%rdx), %r10d
	testb	$-3, %r10b
	movabsq	$434041037028460038, %r10
	cmovneq	%rdi, %r15
	movq	(%rsi,%r15), %rdi
	leaq	(%rdi,%r10), %rbx
	movabsq	$1085102592571150095, %r10
	shrq	$4, %rbx
	andq	%r10, %rbx
	movq	%rdi, %r10
	andq	%rbp, %r10
	movabsq	$9187201950435737471, %rbp
	orq	%rbx, %r10
	movabsq	$3689348814741910323, %rbx
	xorq	%rbx, %r10
	addq	%rbp, %r10
	orq	%rdi, %r10
	andq	%rcx, %r10
	je	.LBB0_113
	tzcntq	%r10, %r10
	movl	%r10d, %ebx
	shrl	$3, %ebx
	je	.LBB0_113
	leal	-4(%rbx), %ebp
	cmpl	$-3, %ebp
	jb	.LBB0_113
	addq	%r15, %rbx
	cmpq	%r11, %rbx
	jne	.LBB0_113
	andb	$56, %r10b
	movabsq	$1085102592571150095, %rcx
	movq	88(%rsp), %rbp
	negb	%r10b
	shlxq	%r10, %rdi, %rdi
	movabsq	$42949672960001, %r10
	andq	%rcx, %rdi
	movabsq	$71777214294589695, %rcx
	imulq	$2561, %rdi, %rdi
	shrq	$8, %rdi
	andq	%rcx, %rdi
	movabsq	$281470681808895, %rcx
	imulq	$6553601, %rdi, %rdi
	shrq	$16, %rdi
	andq	%rcx, %rdi
	imulq	%r10, %rdi
	shrq	$32, %rdi
	movq	%rdi, %r10
	negq	%r10
	cmpb	$45, %dl
	cmovneq	%rdi, %r10
	addq	%r10, %r12
.LBB0_54:
	movq	-40(%rsp), %r10
	testq	%rax, %rax
	je	.LBB0_59
	movabsq	$9007199254740992, %rcx
	cmpq	%rcx, %rax
	ja	.LBB0_60
	leaq	22(%r12), %rdx
	cmpq	$45, %rdx
	jae	.LBB0_60
	movq	-32(%rsp), %rdx
	vcvtsi2sd	%rax, %xmm15, %xmm3
	testq	%r12, %r12
	js	.LBB0_70
	movabsq	$.const.array.data.5, %rax
	vmulsd	(%rax,%r12,8), %xmm3, %xmm3
	cmpb	$45, %r10b
	jne	.LBB0_4
	jmp	.LBB0_88
	.p2align	4
.LBB0_59:
	movq	-32(%rsp), %rdx
	vxorpd	%xmm3, %xmm3, %xmm3
	cmpb	$45, %r10b
	je	.LBB0_88
	jmp	.LBB0_4
	.p2align	4
.LBB0_60:
	leaq	-309(%r12), %rdx
	cmpq	$-651, %rdx
	jb	.LBB0_113
	movq	%rax, %rdx
	shrq	$32, %rdx
	movq	%rax, %rdi
	shlq	$32, %rdi
	xorl	%r10d, %r10d
	movq	%r13, -24(%rsp)
	testq	%rdx, %rdx
	cmovneq	%rax, %rdi
	sete	%r10b
	movq	%rdi, %rdx
	shrq	$48, %rdx
	movq	%rdi, %rbx
	shll	$5, %r10d
	shlq	$16, %rbx
	testq	%rdx, %rdx
	leaq	16(%r10), %r14
	cmovneq	%rdi, %rbx
	cmovneq	%r10, %r14
	movq	%rbx, %rdx
	shrq	$56, %rdx
	movq	%rbx, %rdi
	shlq	$8, %rdi
	leaq	8(%r14), %r10
	testq	%rdx, %rdx
	cmovneq	%rbx, %rdi
	cmovneq	%r14, %r10
	movq	%rdi, %rdx
	shrq	$60, %rdx
	movq	%rdi, %rbx
	shlq	$4, %rbx
	leaq	4(%r10), %r14
	testq	%rdx, %rdx
	cmovneq	%rdi, %rbx
	cmovneq	%r10, %r14
	movq	%rbx, %rdx
	shrq	$62, %rdx
	leaq	(,%rbx,4), %rdi
	leaq	2(%r14), %rcx
	testq	%rdx, %rdx
	movabsq	$.const.array.data.6+2736, %rdx
	movq	(%rdx,%r12,8), %rdx
	cmovneq	%rbx, %rdi
	cmovneq	%r14, %rcx
	testq	%rdi, %rdi
	movq	%rcx, -8(%rsp)
	setns	%cl
	shlxq	%rcx, %rdi, %r14
	movq	%rcx, -16(%rsp)
	movl	%r14d, %r15d
	movq	%r14, %rbx
	shrq	$32, %rbx
	movl	%edx, %ebp
	movq	%rbp, %rdi
	shrq	$32, %rdx
	imulq	%r15, %rdi
	imulq	%rbx, %rbp
	movq	%rdx, %r10
	imulq	%r15, %r10
	imulq	%rbx, %rdx
	movl	%edi, %r13d
	shrq	$32, %rdi
	movl	%r10d, %ecx
	shrq	$32, %r10
	addq	%rdi, %rcx
	movl	%ebp, %edi
	shrq	$32, %rbp
	addq	%rdx, %r10
	addq	%rcx, %rdi
	movq	%rdi, %rdx
	addq	%r10, %rbp
	shrq	$32, %rdx
	shlq	$32, %rdi
	addq	%rbp, %rdx
	orq	%rdi, %r13
	movl	%edx, %ebp
	andl	$511, %ebp
	cmpq	$511, %rbp
	jne	.LBB0_73
	notq	%r14
	cmpq	%r14, %r13
	jbe	.LBB0_73
	movabsq	$.const.array.data.7+2736, %rcx
	movq	(%rcx,%r12,8), %rcx
	movl	%ecx, %edi
	movq	%rdi, %r10
	shrq	$32, %rcx
	imulq	%r15, %r10
	imulq	%rbx, %rdi
	imulq	%rcx, %r15
	imulq	%rbx, %rcx
	movq	%r10, %rbx
	shrq	$32, %rbx
	movl	%r15d, %ebp
	shrq	$32, %r15
	addq	%rbx, %rbp
	movl	%edi, %ebx
	shrq	$32, %rdi
	addq	%rcx, %r15
	addq	%rbp, %rbx
	addq	%r15, %rdi
	movq	%rbx, %r15
	shrq	$32, %r15
	addq	%rdi, %r15
	addq	%r13, %r15
	cmpq	%r13, %r15
	adcq	$0, %rdx
	movl	%edx, %ebp
	andl	$511, %ebp
	cmpq	$-1, %r15
	jne	.LBB0_71
	cmpl	$511, %ebp
	jne	.LBB0_71
	shlq	$32, %rbx
	movl	%r10d, %ecx
	orq	%rbx, %rcx
	cmpq	%r14, %rcx
	jbe	.LBB0_72
	movq	88(%rsp), %rbp
	movq	-48(%rsp), %r14
	movq	-40(%rsp), %r10
	cmpq	$-27, %r12
	jb	.LBB0_114
	leaq	(,%r12,8), %rcx
	movabsq	$.const.array.data.8, %rdx
	movq	-24(%rsp), %r13
	subq	%rcx, %rdx
	movq	%rax, %rcx
	movq	(%rdx), %rdi
	orq	%rdi, %rcx
	shrq	$32, %rcx
	testq	%rcx, %rcx
	je	.LBB0_69
	jne	.LBB0_79
.LBB0_69:
	xorl	%edx, %edx
	divl	%edi
	jmp	.LBB0_85
.LBB0_70:
	shlq	$3, %r12
	movabsq	$.const.array.data.5, %rax
	subq	%r12, %rax
	vdivsd	(%rax), %xmm3, %xmm3
	cmpb	$45, %r10b
	jne	.LBB0_4
	jmp	.LBB0_88
.LBB0_71:
	movq	%r15, %r13
	jmp	.LBB0_73
.LBB0_72:
	movq	$-1, %r13
	movl	$511, %ebp
.LBB0_73:
	movq	-40(%rsp), %r10
	movq	%rdx, %rbx
	shrq	$63, %rbx
	orq	%r13, %rbp
	leal	9(%rbx), %ecx
	shrxq	%rcx, %rdx, %r14
	jne	.LBB0_80
	movq	-24(%rsp), %r13
	movq	88(%rsp), %rbp
	movl	%r14d, %ecx
	andl	$3, %ecx
	cmpl	$1, %ecx
	jne	.LBB0_82
	cmpq	$27, %r12
	jbe	.LBB0_81
	cmpq	$-27, %r12
	jb	.LBB0_113
	leaq	(,%r12,8), %rcx
	movabsq	$.const.array.data.8, %rdx
	subq	%rcx, %rdx
	movq	%rax, %rcx
	movq	(%rdx), %rdi
	orq	%rdi, %rcx
	shrq	$32, %rcx
	testq	%rcx, %rcx
	je	.LBB0_84
	movq	-48(%rsp), %r14
	je	.LBB0_69
.LBB0_79:
	xorl	%edx, %edx
	divq	%rdi
	jmp	.LBB0_86
.LBB0_80:
	movq	-24(%rsp), %r13
	movq	88(%rsp), %rbp
	jmp	.LBB0_82
.LBB0_81:
	movl	$512, %eax
	shlxq	%rbx, %rax, %rax
	decq	%rax
	andq	%rdx, %rax
	cmpq	$1, %rax
	sbbq	$0, %r14
.LBB0_82:
	movq	-16(%rsp), %rax
	xorl	%ecx, %ecx
	movl	%r14d, %edx
	andl	$1, %edx
	addq	%r14, %rdx
	movb	%al, %cl
	imulq	$217706, %r12, %rax
	negq	%rcx
	subq	-8(%rsp), %rcx
	sarq	$16, %rax
	addq	%rcx, %rax
	movq	%rdx, %rcx
	shrq	$54, %rcx
	addq	%rbx, %rax
	cmpq	$1, %rcx
	sbbq	$-1, %rax
	leaq	-961(%rax), %rcx
	cmpq	$-2046, %rcx
	jb	.LBB0_113
	movabsq	$18014398509481983, %rcx
	addq	$1086, %rax
	movq	-48(%rsp), %r14
	cmpq	%rdx, %rcx
	movl	$0, %ecx
	adcb	$1, %cl
	shrxq	%rcx, %rdx, %rcx
	movabsq	$.const.array.data.9, %rdx
	vcvtsi2sd	%rcx, %xmm15, %xmm3
	vmulsd	(%rdx,%rax,8), %xmm3, %xmm3
	movq	-32(%rsp), %rdx
	cmpb	$45, %r10b
	jne	.LBB0_4
	jmp	.LBB0_88
.LBB0_84:
	xorl	%edx, %edx
	divl	%edi
	movq	-48(%rsp), %r14
.LBB0_85:
.LBB0_86:
	testq	%rdx, %rdx
	jne	.LBB0_113
	vmovq	%rax, %xmm3
	movabsq	$.const.array.data.9+8600, %rax
	movq	-32(%rsp), %rdx
	vpunpckldq	%xmm1, %xmm3, %xmm3
	vsubpd	%xmm2, %xmm3, %xmm3
	vshufpd	$1, %xmm3, %xmm3, %xmm4
	vaddsd	%xmm3, %xmm4, %xmm3
	vmulsd	(%rax,%r12,8), %xmm3, %xmm3
	cmpb	$45, %r10b
	jne	.LBB0_4
	jmp	.LBB0_88
.LBB0_89:
	cmpq	%rbp, %r11
	jge	.LBB0_95
	movzbl	(%rsi,%r11), %eax
	cmpb	$33, %al
	setae	%dl
	cmpb	$10, %al
	sete	%al
	orb	%dl, %al
	jne	.LBB0_95
.LBB0_91:
	leaq	1(%r11), %rax
	cmpq	%rbp, %rax
	jge	.LBB0_98
	movzbl	1(%rsi,%r11), %edx
	cmpb	$32, %dl
	ja	.LBB0_96
	movq	%rax, %r11
	cmpb	$10, %dl
	jne	.LBB0_91
	jmp	.LBB0_96
.LBB0_95:
	movq	%r11, %rax
.LBB0_96:
	cmpq	%rbp, %rax
	jge	.LBB0_99
	cmpb	$10, (%rsi,%rax)
	movq	$-1, %r9
	je	.LBB0_99
	jmp	.LBB0_113
.LBB0_98:
	movq	%rbp, %rax
.LBB0_99:
	incq	%r14
	incq	%rax
	movq	%r14, %r9
	cmpq	%rbp, %rax
	jl	.LBB0_3
	jmp	.LBB0_113
.LBB0_100:
	movq	%r14, %r9
	jmp	.LBB0_113
.LBB0_101:
	movq	%r14, %r9
	jmp	.LBB0_104
.LBB0_102:
	movq	%rbp, %rax
	.p2align	4
.LBB0_103:
	incq	%r9
	incq	%rax
	cmpq	%rbp, %rax
	jge	.LBB0_113
.LBB0_104:
	cmpq	%rbp, %rax
	jge	.LBB0_109
	movzbl	(%rsi,%rax), %ecx
	cmpb	$33, %cl
	setae	%dl
	cmpb	$10, %cl
	sete	%cl
	orb	%dl, %cl
	jne	.LBB0_109
	.p2align	4
.LBB0_106:
	cmpq	%rax, %r8
	je	.LBB0_102
	movzbl	1(%rsi,%rax), %edx
	incq	%rax
	cmpb	$32, %dl
	ja	.LBB0_109
	cmpb	$10, %dl
	jne	.LBB0_106
	.p2align	4
.LBB0_109:
	cmpq	%rbp, %rax
	jge	.LBB0_103
	cmpb	$10, (%rsi,%rax)
	je	.LBB0_103
.LBB0_112:
	movq	$-1, %r9
.LBB0_113:
	movq	%r9, (%r13)
	xorl	%eax, %eax
	popq	%rbx
	popq	%r12
	popq	%r13
	popq	%r14
	popq	%r15
	popq	%rbp
	retq
.LBB0_114:
	movq	-24(%rsp), %r13
	jmp	.LBB0_113
