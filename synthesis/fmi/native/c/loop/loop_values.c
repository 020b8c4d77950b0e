/* loop_values.c -- the closed-loop engine's get and set (the time, value reference 0, or a
 * component's variable, by the mapping of resources/loop.txt) and the FMI functions a closed
 * loop does not support (see closed_loop.c).  unsupported and none_of are also the messages of
 * the engine's FMI 3.0 face (../fmi3/fmi3_cs.c compiled with FMI3_OVER_LOOP). */
#include <stdio.h>
#include <string.h>

#include "loop.h"

fmi2Status set_one(Part *p, char type, fmi2ValueReference vr, const void *value)
{
    if (type == 'R')
        return p->set_real(p->c, &vr, 1, (const fmi2Real *)value);
    if (type == 'I')
        return p->set_int(p->c, &vr, 1, (const fmi2Integer *)value);
    return p->set_bool(p->c, &vr, 1, (const fmi2Boolean *)value);
}

fmi2Status get_one(Part *p, char type, fmi2ValueReference vr, void *value)
{
    if (type == 'R')
        return p->get_real(p->c, &vr, 1, (fmi2Real *)value);
    if (type == 'I')
        return p->get_int(p->c, &vr, 1, (fmi2Integer *)value);
    return p->get_bool(p->c, &vr, 1, (fmi2Boolean *)value);
}

static LoopVar *find_var(Loop *L, fmi2ValueReference vr, char type)
{
    for (size_t i = 0; i < L->nvars; i++)
        if (L->vars[i].vr == vr)
            return L->vars[i].type == type ? &L->vars[i] : NULL;
    return NULL;
}

/* -- get and set: the time (value reference 0) or a component's variable ---------------------- */

static fmi2Status get_values(Loop *L, const fmi2ValueReference vr[], size_t n, char type,
                             void *values, size_t size)
{
    if (L == NULL)
        return fmi2Error;
    for (size_t i = 0; i < n; i++) {
        void *value = (char *)values + i * size;
        LoopVar *v;
        if (type == 'R' && vr[i] == 0) {
            *(fmi2Real *)value = L->t;
            continue;
        }
        if ((v = find_var(L, vr[i], type)) == NULL) {
            loop_error(L, "no %s variable has value reference %u",
                       type == 'R' ? "Real" : type == 'I' ? "Integer" : "Boolean", vr[i]);
            return fmi2Error;
        }
        if (get_one(&L->part[v->comp], type, v->cvr, value) > fmi2Warning) {
            loop_error(L, "reading value reference %u of the %s failed", v->cvr,
                       L->part[v->comp].role);
            return fmi2Error;
        }
    }
    return fmi2OK;
}

static fmi2Status set_values(Loop *L, const fmi2ValueReference vr[], size_t n, char type,
                             const void *values, size_t size)
{
    if (L == NULL)
        return fmi2Error;
    for (size_t i = 0; i < n; i++) {
        const void *value = (const char *)values + i * size;
        LoopVar *v = find_var(L, vr[i], type);
        fmi2Status st;
        if (v == NULL || !v->settable) {
            loop_error(L, v == NULL ? "no settable %s variable has value reference %u"
                                    : "the %s variable of value reference %u is an output",
                       type == 'R' ? "Real" : type == 'I' ? "Integer" : "Boolean", vr[i]);
            return fmi2Error;
        }
        if ((st = set_one(&L->part[v->comp], type, v->cvr, value)) > fmi2Warning)
            return st;           /* the component logged why */
        if ((long)v->vr == L->period_vr)
            L->T = type == 'R' ? *(const fmi2Real *)value : (double)*(const fmi2Integer *)value;
    }
    return fmi2OK;
}

fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Real v[])
{
    return get_values((Loop *)c, vr, n, 'R', v, sizeof *v);
}

fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                          fmi2Integer v[])
{
    return get_values((Loop *)c, vr, n, 'I', v, sizeof *v);
}

fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                          fmi2Boolean v[])
{
    return get_values((Loop *)c, vr, n, 'B', v, sizeof *v);
}

fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                       const fmi2Real v[])
{
    return set_values((Loop *)c, vr, n, 'R', v, sizeof *v);
}

fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                          const fmi2Integer v[])
{
    return set_values((Loop *)c, vr, n, 'I', v, sizeof *v);
}

fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                          const fmi2Boolean v[])
{
    return set_values((Loop *)c, vr, n, 'B', v, sizeof *v);
}

/* -- what a closed loop does not support ------------------------------------------------------- */

static fmi2Status unsupported(fmi2Component c, const char *what)
{
    if (c != NULL)
        loop_error((Loop *)c, "%s is not supported by this closed-loop FMU", what);
    return fmi2Error;
}

/* a call about variables of a type the closed loop has none of: fine when it names none */
static fmi2Status none_of(fmi2Component c, size_t n, const char *type)
{
    if (n == 0)
        return fmi2OK;
    if (c != NULL)
        loop_error((Loop *)c, "this closed-loop FMU has no %s variables", type);
    return fmi2Error;
}

fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                         fmi2String v[])
{
    (void)vr, (void)v;
    return none_of(c, n, "String");
}

fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                         const fmi2String v[])
{
    (void)vr, (void)v;
    return none_of(c, n, "String");
}

fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *s)
{
    (void)s;
    return unsupported(c, "fmi2GetFMUstate");
}

fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate s)
{
    (void)s;
    return unsupported(c, "fmi2SetFMUstate");
}

fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *s)
{
    (void)s;
    return unsupported(c, "fmi2FreeFMUstate");
}

fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate s, size_t *n)
{
    (void)s, (void)n;
    return unsupported(c, "fmi2SerializedFMUstateSize");
}

fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate s, fmi2Byte b[], size_t n)
{
    (void)s, (void)b, (void)n;
    return unsupported(c, "fmi2SerializeFMUstate");
}

fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte b[], size_t n,
                                   fmi2FMUstate *s)
{
    (void)s, (void)b, (void)n;
    return unsupported(c, "fmi2DeSerializeFMUstate");
}

fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference u[],
                                        size_t nu, const fmi2ValueReference k[], size_t nk,
                                        const fmi2Real dk[], fmi2Real du[])
{
    (void)u, (void)nu, (void)k, (void)nk, (void)dk, (void)du;
    return unsupported(c, "fmi2GetDirectionalDerivative");
}

fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[],
                                       size_t n, const fmi2Integer order[],
                                       const fmi2Real value[])
{
    (void)vr, (void)n, (void)order, (void)value;
    return unsupported(c, "fmi2SetRealInputDerivatives");
}

fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[],
                                        size_t n, const fmi2Integer order[],
                                        fmi2Real value[])
{
    (void)vr, (void)n, (void)order, (void)value;
    return unsupported(c, "fmi2GetRealOutputDerivatives");
}

fmi2Status fmi2CancelStep(fmi2Component c)
{
    return unsupported(c, "fmi2CancelStep");
}

fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind s, fmi2Status *v)
{
    (void)s, (void)v;
    return unsupported(c, "fmi2GetStatus");
}

fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind s, fmi2Real *v)
{
    Loop *L = (Loop *)c;
    if (L != NULL && s == fmi2LastSuccessfulTime) {
        *v = L->t;
        return fmi2OK;
    }
    return unsupported(c, "fmi2GetRealStatus");
}

fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind s, fmi2Integer *v)
{
    (void)s, (void)v;
    return unsupported(c, "fmi2GetIntegerStatus");
}

fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind s, fmi2Boolean *v)
{
    (void)s, (void)v;
    return unsupported(c, "fmi2GetBooleanStatus");
}

fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind s, fmi2String *v)
{
    (void)s, (void)v;
    return unsupported(c, "fmi2GetStringStatus");
}
