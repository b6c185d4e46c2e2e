//! `#[derive(Words)]` for pmsm-core's drive images (`pmsm_core::DriveConfig::write_image`,
//! docs/image.md): a value as a fixed number of 32-bit words, written on the host and read on
//! a target without `unsafe` and without the layout of either.
//!
//! The derive is for pmsm-core's own types: the code it generates names `crate::image`.
//!
//! - A struct is its fields in declaration order. A field under `#[cfg(...)]` is imaged under
//!   the same condition; a field marked `#[words(skip)]` is not imaged and reads back as its
//!   `Default`.
//! - An enum is a tag word (the variant's index in declaration order, also counting variants
//!   left out by `#[cfg]`), the variant's fields, then zero words up to the longest variant,
//!   so that every value of a type has the same length (`Words::WORDS`).
//! - `Words::SCHEMA` folds the type's name, its fields' and variants' names and their types'
//!   schemas: an image read as a type of another shape, or of another build's features, is
//!   refused rather than misread.
//! - `Words::FLOATS` counts the `f32` and `f64` values among the words (an enum's over all
//!   its variants): what the interrupt side keeps is checked to have none.

use proc_macro::TokenStream;
use proc_macro2::{Span, TokenStream as TokenStream2};
use quote::{format_ident, quote};
use syn::{
    Attribute, Data, DeriveInput, Error, Fields, GenericParam, Index, parse_macro_input,
    parse_quote,
};

/// Derives `crate::image::Words` (see the crate's documentation).
#[proc_macro_derive(Words, attributes(words))]
pub fn derive_words(input: TokenStream) -> TokenStream {
    let input = parse_macro_input!(input as DeriveInput);
    expand(input)
        .unwrap_or_else(Error::into_compile_error)
        .into()
}

/// The `#[cfg(...)]` attributes of an item, to repeat on the code generated for it.
fn cfgs(attrs: &[Attribute]) -> Vec<&Attribute> {
    attrs.iter().filter(|a| a.path().is_ident("cfg")).collect()
}

/// Whether a field carries `#[words(skip)]`.
fn skipped(attrs: &[Attribute]) -> syn::Result<bool> {
    let mut skip = false;
    for a in attrs.iter().filter(|a| a.path().is_ident("words")) {
        a.parse_nested_meta(|m| {
            if m.path.is_ident("skip") {
                skip = true;
                Ok(())
            } else {
                Err(m.error("expected `skip`"))
            }
        })?;
    }
    Ok(skip)
}

/// One imaged field: how to name it in a pattern or literal, its type, its cfgs.
struct Field<'a> {
    member: syn::Member,
    binding: syn::Ident,
    ty: &'a syn::Type,
    cfgs: Vec<&'a Attribute>,
    skip: bool,
}

fn fields(fields: &Fields) -> syn::Result<Vec<Field<'_>>> {
    fields
        .iter()
        .enumerate()
        .map(|(i, f)| {
            let (member, binding) = match &f.ident {
                Some(id) => (syn::Member::Named(id.clone()), format_ident!("f_{}", id)),
                None => (
                    syn::Member::Unnamed(Index::from(i)),
                    format_ident!("f_{}", i),
                ),
            };
            let cfgs = cfgs(&f.attrs);
            if f.ident.is_none() && !cfgs.is_empty() {
                return Err(Error::new_spanned(
                    f,
                    "`#[cfg]` on a tuple field is not supported",
                ));
            }
            Ok(Field {
                member,
                binding,
                ty: &f.ty,
                cfgs,
                skip: skipped(&f.attrs)?,
            })
        })
        .collect()
}

/// `let n = n + <T as Words>::WORDS;` per imaged field, each under its cfgs: the words of a
/// field list, starting from `n` as it is.
fn count(fields: &[Field<'_>]) -> TokenStream2 {
    let lines = fields.iter().filter(|f| !f.skip).map(|f| {
        let (ty, cfgs) = (f.ty, &f.cfgs);
        quote! { #(#cfgs)* let n = n + <#ty as crate::image::Words>::WORDS; }
    });
    quote! { #(#lines)* }
}

/// `let n = n + <T as Words>::FLOATS;` per imaged field, each under its cfgs: the
/// floating-point values of a field list, starting from `n` as it is.
fn count_floats(fields: &[Field<'_>]) -> TokenStream2 {
    let lines = fields.iter().filter(|f| !f.skip).map(|f| {
        let (ty, cfgs) = (f.ty, &f.cfgs);
        quote! { #(#cfgs)* let n = n + <#ty as crate::image::Words>::FLOATS; }
    });
    quote! { #(#lines)* }
}

/// The schema's fold over a field list, starting from `h` as it is.
fn schema(fields: &[Field<'_>]) -> TokenStream2 {
    let lines = fields.iter().filter(|f| !f.skip).map(|f| {
        let (ty, cfgs) = (f.ty, &f.cfgs);
        let name = match &f.member {
            syn::Member::Named(id) => id.to_string(),
            syn::Member::Unnamed(i) => i.index.to_string(),
        };
        quote! {
            #(#cfgs)* let h = crate::image::mix(
                crate::image::mix(h, crate::image::hash(#name)),
                <#ty as crate::image::Words>::SCHEMA,
            );
        }
    });
    quote! { #(#lines)* }
}

/// The put of each imaged field, by its binding.
fn puts(fields: &[Field<'_>]) -> TokenStream2 {
    let lines = fields.iter().filter(|f| !f.skip).map(|f| {
        let (b, cfgs) = (&f.binding, &f.cfgs);
        quote! { #(#cfgs)* crate::image::Words::put(#b, out); }
    });
    quote! { #(#lines)* }
}

/// A literal of the fields read in order (`Self { .. }` or `Self::V(..)`), after `path`.
fn literal(path: TokenStream2, fields: &Fields, list: &[Field<'_>]) -> TokenStream2 {
    let values = list.iter().map(|f| {
        if f.skip {
            quote! { ::core::default::Default::default() }
        } else {
            quote! { crate::image::Words::get(r) }
        }
    });
    match fields {
        Fields::Named(_) => {
            let inits = list.iter().zip(values).map(|(f, v)| {
                let (m, cfgs) = (&f.member, &f.cfgs);
                quote! { #(#cfgs)* #m: #v }
            });
            quote! { #path { #(#inits),* } }
        }
        Fields::Unnamed(_) => quote! { #path ( #(#values),* ) },
        Fields::Unit => path,
    }
}

/// The pattern binding every field of `fields` after `path`.
fn pattern(path: TokenStream2, fields: &Fields, list: &[Field<'_>]) -> TokenStream2 {
    match fields {
        Fields::Named(_) => {
            let binds = list.iter().map(|f| {
                let (m, b, cfgs) = (&f.member, &f.binding, &f.cfgs);
                quote! { #(#cfgs)* #m: #b }
            });
            quote! { #path { #(#binds),* } }
        }
        Fields::Unnamed(_) => {
            let binds = list.iter().map(|f| &f.binding);
            quote! { #path ( #(#binds),* ) }
        }
        Fields::Unit => path,
    }
}

fn expand(mut input: DeriveInput) -> syn::Result<TokenStream2> {
    let name = &input.ident;
    let type_name = name.to_string();
    // Every type parameter must have an image itself.
    let params: Vec<_> = input
        .generics
        .params
        .iter()
        .filter_map(|p| match p {
            GenericParam::Type(t) => Some(t.ident.clone()),
            _ => None,
        })
        .collect();
    {
        let clause = input.generics.make_where_clause();
        for p in &params {
            clause
                .predicates
                .push(parse_quote!(#p: crate::image::Words));
        }
    }
    let (impl_generics, ty_generics, where_clause) = input.generics.split_for_impl();

    let (words, schema_fold, floats, put_body, get_body) = match &input.data {
        Data::Struct(s) => {
            let list = fields(&s.fields)?;
            let n = count(&list);
            let fl = count_floats(&list);
            let h = schema(&list);
            let pat = pattern(quote!(Self), &s.fields, &list);
            let put = puts(&list);
            let lit = literal(quote!(Self), &s.fields, &list);
            let unused = list.iter().filter(|f| f.skip).map(|f| &f.binding);
            (
                quote! { { let n = 0usize; #n n } },
                quote! { { let h = crate::image::hash(#type_name); #h h } },
                quote! { { let n = 0usize; #fl n } },
                quote! {
                    let #pat = self;
                    #( let _ = #unused; )*
                    #put
                },
                quote! { #lit },
            )
        }
        Data::Enum(e) => {
            let mut longest = Vec::new();
            let mut hashes = Vec::new();
            let mut float_sums = Vec::new();
            let mut put_arms = Vec::new();
            let mut get_arms = Vec::new();
            // The fallback of a tag that names no variant: the first variant built in (each
            // variant's cfg, and none of the earlier ones').
            let mut fallbacks = Vec::new();
            let mut earlier: Vec<TokenStream2> = Vec::new();
            for (tag, v) in e.variants.iter().enumerate() {
                let tag =
                    u32::try_from(tag).map_err(|_| Error::new_spanned(v, "too many variants"))?;
                let vname = &v.ident;
                let vstr = vname.to_string();
                let vcfgs = cfgs(&v.attrs);
                let list = fields(&v.fields)?;
                if list.iter().any(|f| f.skip || !f.cfgs.is_empty()) {
                    return Err(Error::new_spanned(
                        v,
                        "`#[cfg]` and `#[words(skip)]` on a variant's field are not supported",
                    ));
                }
                let n = count(&list);
                let h = schema(&list);
                let fl = count_floats(&list);
                float_sums.push(quote! {
                    #(#vcfgs)* let f = f + { let n = 0usize; #fl n };
                });
                longest.push(quote! {
                    #(#vcfgs)* let m = crate::image::max(m, { let n = 0usize; #n n });
                });
                hashes.push(quote! {
                    #(#vcfgs)* let h = crate::image::mix(
                        crate::image::mix(h, crate::image::hash(#vstr)),
                        { let h = #tag; #h h },
                    );
                });
                let pat = pattern(quote!(Self::#vname), &v.fields, &list);
                let put = puts(&list);
                put_arms.push(quote! {
                    #(#vcfgs)* #pat => {
                        out.word(#tag);
                        #put
                        out.pad(<Self as crate::image::Words>::WORDS - 1 - { let n = 0usize; #n n });
                    }
                });
                let lit = literal(quote!(Self::#vname), &v.fields, &list);
                let read = quote! {{
                    let v = #lit;
                    r.skip(<Self as crate::image::Words>::WORDS - 1 - { let n = 0usize; #n n });
                    v
                }};
                get_arms.push(quote! { #(#vcfgs)* #tag => #read, });
                let preds: Vec<TokenStream2> = vcfgs
                    .iter()
                    .map(|a| a.parse_args::<TokenStream2>())
                    .collect::<syn::Result<_>>()?;
                let this = quote! { all(#(#preds),*) };
                fallbacks.push(quote! {
                    #[cfg(all(#this, not(any(#(#earlier),*))))]
                    let v = #read;
                });
                earlier.push(this);
            }
            (
                quote! { { let m = 0usize; #(#longest)* 1 + m } },
                quote! { { let h = crate::image::hash(#type_name); #(#hashes)* h } },
                quote! { { let f = 0usize; #(#float_sums)* f } },
                quote! { match self { #(#put_arms)* } },
                quote! {
                    match r.word() {
                        #(#get_arms)*
                        _ => {
                            r.invalid();
                            #(#fallbacks)*
                            v
                        }
                    }
                },
            )
        }
        Data::Union(_) => {
            return Err(Error::new(Span::call_site(), "a union has no image"));
        }
    };

    Ok(quote! {
        #[automatically_derived]
        impl #impl_generics crate::image::Words for #name #ty_generics #where_clause {
            const WORDS: usize = #words;
            const SCHEMA: u32 = #schema_fold;
            const FLOATS: usize = #floats;
            #[allow(unused_variables)]
            fn put(&self, out: &mut crate::image::WordWriter<'_>) {
                #put_body
            }
            #[allow(unused_variables)]
            fn get(r: &mut crate::image::WordReader<'_>) -> Self {
                #get_body
            }
        }
    })
}
