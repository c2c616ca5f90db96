//! The object builder of [`super::StoneSoupKit`]: one Stone Soup class made from a
//! specification of `usvfast.stonesoup_objects`, without its constructor.

use super::*;
use pyo3::types::{PyString, PyTuple};

/// One Stone Soup class: `cls.__new__(cls)`, then its `__dict__` entries set one by one in
/// the class's order (`template`'s keys, or `keys` without a template) to the values given
/// (`keys`) or the template's constants — as `usvfast.stonesoup_objects` fills `__dict__`,
/// but through the instance's own attribute storage (CPython then shares the class's key
/// table, as for the objects Stone Soup's constructors make, and makes no separate dict).
pub(super) struct Builder {
    new: Py<PyAny>,
    pub(super) cls: Py<PyAny>,
    n_args: usize,
    /// `__dict__` key and where its value comes from: argument i or a constant.
    order: Vec<(Py<PyString>, Source)>,
    /// The class's `tp_new` slot when `new` is `object.__new__` (what `object.__new__(cls)`
    /// runs, without the call through Python).
    tp_new: Option<pyo3::ffi::newfunc>,
}

/// `key` interned (the attribute names of the objects Stone Soup's constructors make are: a
/// store then finds its slot in the class's shared key table by identity, not by comparing
/// the characters).
fn interned(key: &Bound<'_, PyString>) -> PyResult<Py<PyString>> {
    Ok(PyString::intern(key.py(), key.to_str()?).unbind())
}

enum Source {
    Arg(usize),
    Const(Py<PyAny>),
}

impl Builder {
    pub(super) fn from_spec(spec: &Bound<'_, PyAny>) -> PyResult<Self> {
        type Spec<'py> = (
            Bound<'py, PyAny>,
            Bound<'py, PyAny>,
            Vec<Bound<'py, PyString>>,
            Option<Bound<'py, PyDict>>,
        );
        let (new, cls, keys, template): Spec<'_> = spec.extract()?;
        let py = spec.py();
        let object_new = py.get_type::<pyo3::types::PyAny>().getattr("__new__")?;
        let tp_new = match cls.cast::<PyType>() {
            Ok(t) if new.is(&object_new) => {
                // SAFETY: a type object; the slot is object_new or inherited from a base.
                let slot =
                    unsafe { pyo3::ffi::PyType_GetSlot(t.as_type_ptr(), pyo3::ffi::Py_tp_new) };
                if slot.is_null() {
                    None
                } else {
                    // SAFETY: the Py_tp_new slot holds a newfunc.
                    Some(unsafe {
                        std::mem::transmute::<*mut std::ffi::c_void, pyo3::ffi::newfunc>(slot)
                    })
                }
            }
            _ => None,
        };
        let arg_of = |k: &Bound<'_, PyAny>| -> PyResult<Option<usize>> {
            for (i, a) in keys.iter().enumerate() {
                if a.as_any().eq(k)? {
                    return Ok(Some(i));
                }
            }
            Ok(None)
        };
        let mut order = Vec::new();
        match &template {
            Some(t) => {
                for (k, v) in t.iter() {
                    let src = match arg_of(&k)? {
                        Some(i) => Source::Arg(i),
                        None => Source::Const(v.unbind()),
                    };
                    order.push((interned(&k.cast_into::<PyString>()?)?, src));
                }
                if order
                    .iter()
                    .filter(|(_, s)| matches!(s, Source::Arg(_)))
                    .count()
                    != keys.len()
                {
                    return Err(PyValueError::new_err(
                        "builders: every key must be in the template",
                    ));
                }
            }
            None => {
                for (i, k) in keys.iter().enumerate() {
                    order.push((interned(k)?, Source::Arg(i)));
                }
            }
        }
        Ok(Self {
            tp_new,
            new: new.unbind(),
            cls: cls.unbind(),
            n_args: keys.len(),
            order,
        })
    }

    pub(super) fn make<'py>(
        &self,
        py: Python<'py>,
        values: &[&Bound<'py, PyAny>],
    ) -> PyResult<Bound<'py, PyAny>> {
        if values.len() != self.n_args {
            return Err(PyValueError::new_err(format!(
                "values: expected {} values, got {}",
                self.n_args,
                values.len()
            )));
        }
        let cls = self.cls.bind(py);
        let obj = match self.tp_new {
            // SAFETY: `cls` is a type whose tp_new is `f`; empty arguments as `cls.__new__(cls)`.
            Some(f) => unsafe {
                let args = PyTuple::empty(py);
                let ptr = f(cls.as_ptr().cast(), args.as_ptr(), std::ptr::null_mut());
                Bound::from_owned_ptr_or_err(py, ptr)?
            },
            None => self.new.bind(py).call1((cls,))?,
        };
        for (k, src) in &self.order {
            let v = match src {
                Source::Arg(i) => values[*i].as_ptr(),
                Source::Const(c) => c.as_ptr(),
            };
            // SAFETY: valid object, key and value; the generic setter stores into the
            // instance's attribute storage (these classes define no `__setattr__`, and no
            // descriptor is named `_property_<name>`).
            let rc = unsafe { pyo3::ffi::PyObject_GenericSetAttr(obj.as_ptr(), k.as_ptr(), v) };
            if rc != 0 {
                return Err(PyErr::fetch(py));
            }
        }
        Ok(obj)
    }
}
